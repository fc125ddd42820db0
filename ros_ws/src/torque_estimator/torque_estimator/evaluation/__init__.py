"""The accuracy studies (``make evaluate``): each estimator and tool measured on the simulated rig.

``evaluate`` (the CLI: every table and one summary line per study), ``held_out`` (the paper's
Table 3: an estimator on held-out operating points), ``transient`` (a load step, a speed ramp and a
reversal streamed as estimator_node runs them), ``identified`` (one ``identify`` run against the
k-NN grid), ``observer_study`` (the observer's steady noise and its model errors),
``residual_cases`` (a folder: the residuals tool's case matrix), ``real_drive`` (a real worm drive's
measurements, the T-RO 2021 data, through ``identify`` and ``estimate``: their published fit beside
identify's, the load estimated cross-fitted, the start-stop runs), ``tro2021_model`` (the T-RO paper's
model with their parameters, the reference), ``foreign`` (drives the project did
not make: a plant of their own equations, imports nothing of the project), ``datasheet_road`` (on
those drives: rig_from_datasheet, identify, estimate, as a user walks it), ``closed_loop`` (the
speed loop with
feedforward in one process, at the rig's, the firmware's and the graph's timing; the controller
benchmark's core), ``scenario`` (timelines of speed and load segments, played in-process by
``closed_loop`` and live by the demo), ``plots`` (PNGs).
"""
