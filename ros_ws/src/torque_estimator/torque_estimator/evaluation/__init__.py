"""The accuracy studies (``make evaluate``): each estimator and tool measured on the simulated rig.

``evaluate`` (the CLI: every table and one summary line per study), ``held_out`` (the paper's
Table 3: an estimator on held-out operating points), ``transient`` (a load step, a speed ramp and a
reversal streamed as estimator_node runs them), ``identified`` (one ``identify`` run against the
k-NN grid), ``observer_study`` (the observer's steady noise and its model errors),
``residual_cases`` (the residuals tool's case matrix), ``real_drive`` (the model against a real
worm drive's measurements, the T-RO 2021 data: their published fit beside ours, the load
estimated cross-fitted), ``start_stop`` (the momentum observer on that drive's start-stop runs, the only real
transient data), ``steady_fit`` (our model fitted to steady points, and the residual
selection of what it lacks), ``tro2021_model`` (the T-RO paper's model with their parameters,
the reference), ``closed_loop`` (the speed loop with
feedforward in one process, at the rig's, the firmware's and the graph's timing; the controller
benchmark's core), ``scenario`` (timelines of speed and load segments, played in-process by
``closed_loop`` and live by the demo), ``plots`` (PNGs).
"""
