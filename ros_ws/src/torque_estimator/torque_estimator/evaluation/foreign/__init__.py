"""A worm drive that is not ours: an independent simulator, for validation data the project's model did not make.

Nothing here imports the project's packages (worm_model, worm_rig_driver, torque_estimator): the equations are
written again from textbook worm-gear mechanics (tooth-normal force resolved at the pitch point, Coulomb friction
along the thread, a PMDC motor, stick at standstill), so that agreement between the project's estimators and this
plant says something about the estimators rather than about one set of equations agreeing with itself.

- ``drives``: three example drives, each with its catalogue numbers (what a user types into a datasheet tool)
  and its hidden truth (friction, drags, inertias, sensors).
- ``plant``: the simulator (``simulate``) and the quasi-static relations it obeys (``steady_current``).
- ``recordings``: profiles (excitation, validation, start-stop, held points, released motor), the CSV writer
  of the ``worm_rig_data`` schema, and a small CLI::

      python -m torque_estimator.evaluation.foreign.recordings --drive foreign30 --kind excitation \
          --seconds 240 --seed 1 --out f.csv
"""
