"""Closing the loop with measured data (physics.md section 9).

Modules (plain Python, no ROS), in the order the analysis uses them:
  ``data``           the input: a ``worm_rig_data`` CSV (schema, reader, writer: worm_model.rig_data.schema) or a bag
                     via worm_rig_driver
  ``model``          the drive current the declared model predicts, plus effect channels; the transmission
                     error ratio*theta_worm - theta_gear when the data has a gear encoder
  ``free``           which rig parameters a fit may change (the rig file's ``free:`` list, the standard refit set,
                     each friction model's mu parameter), their tolerance bands and physical bounds
  ``effects``        the candidate effects' regressors, the analysis's face of worm_model.effects' vocabulary
                     (Protocol + registry EFFECTS; a folder: its own map)
  ``settings``       the options of an analysis
  ``fitting``        the fits and their judges: held-out split, fits to the training samples (Problem and Fit),
                     screening of candidates, acceptance (a folder: its own map)
  ``description``    what is left, described: residual descriptors, the noise floor and the unexplained residual,
                     aliases of refitted parameters, unique contributions (a folder: its own map)
  ``selection``      forward selection and backward elimination (on ``fitting`` and ``description``)
  ``analysis``       the procedure, step by step (``analyse``), and the names callers need
  ``extended``       the extended model: parameter file with ``effects:``, current and tau_d for estimators
  ``report``         report.json, PNG plots, console summary
  ``cli``            the ``residuals`` executable

Read first: ``analysis`` (the steps), then ``free`` (what is corrected, and why).  The folders depend one
way: ``description`` on ``fitting``, never back; ``selection`` and ``analysis`` on both.
"""
