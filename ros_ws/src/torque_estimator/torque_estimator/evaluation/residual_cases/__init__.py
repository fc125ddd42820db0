"""The residual tool's case matrix: `residuals` on the project's simulator, true effects against found ones.

Each case simulates a few seconds of n rigs side by side (worm_rig_driver's SimulatedRig, its
effect plug-ins switched on, the model not told) and gives the analysis a *rig file*, written
to disk as a user writes one, its declared numbers off by realistic amounts (``rig_files``).  The
analysis reads that file as the ``residuals`` executable does (``load_rig``, its ``free:`` list).

So that the matrix cannot be passed by one rig file's choices it spans the rig-file options
(``rig_files.RIGS``): two rigs (the bundled NMRV030 and a size-040 variant with another ratio, motor,
load motor count, current sensor: ``worm_model/data/nmrv040_rig.yaml``), each under every
friction model of worm_model.physics.friction.FRICTION_MODELS (the plant follows the rig file's
model; its mu is the file's).  A plant may differ from its file beyond the declared values
(``Case.plant``: e.g. no drag at all, where a fit that trades the drags against the rest goes
negative).

It lives here, with the studies, because it needs both the residual analysis
(worm_model) and the simulator (worm_rig_driver).

Map (dependencies point up this list):

``rig_files`` (the rigs the matrix uses, the declared-value errors, and the rig file a user writes:
``write_rig_file``), ``case`` (what a case is, and its result with the pass rule), ``simulation`` (a
case's data on the simulator: the excitation profiles, the effects outside the vocabulary, ``simulate``),
``runner`` (``run_case``: simulate, write the rig file, analyse; ``run_matrix``: a list of cases in
worker processes), ``catalogue`` (the effect sizes and the cases: ``families``, ``full_matrix`` (what
``make evaluate`` prints), ``small_matrix`` (``--residual-cases small``, a subset)), ``report`` (the
lines ``make evaluate`` prints: per case, the confusion table, per family, last ``summary_line``),
``__main__`` (the command line: ``python -m torque_estimator.evaluation.residual_cases --family NAME``
runs one family).
"""
