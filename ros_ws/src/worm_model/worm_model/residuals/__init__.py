"""Closing the loop with measured data (physics.md section 9).

Modules (plain Python, no ROS), in the order the analysis uses them:
  ``data``           the input: a ``worm_rig_data`` CSV (schema, reader, writer: worm_model.rig_data.schema) or a bag
                     via worm_rig_driver
  ``model``          the drive current the declared model predicts, plus effect channels; the transmission
                     error ratio*theta_worm - theta_gear when the data has a gear encoder
  ``free``           which rig parameters a fit may change (the rig file's ``free:`` list, the standard refit set,
                     each friction model's mu parameter), their tolerance bands and physical bounds
  ``effects``        candidate effects as plug-ins (Protocol + registry EFFECTS)
  ``settings``       the options of an analysis
  ``split``          the held-out split: interleaved time blocks with guards
  ``fitting``        fits of the model to the training samples (current; transmission error), Problem and Fit
  ``screening``      every candidate ranked by the held-out error it would leave
  ``acceptance``     when a fit earns its keep: held-out improvement, block bootstrap, BIC, physical range
  ``selection``      forward selection and backward elimination
  ``descriptors``    generic descriptions of a residual (binned means, angle orders) and the pseudo-effect of one
  ``aliases``        effects named from a refitted parameter beyond its tolerance band
  ``contributions``  what each named effect buys on held-out data
  ``unexplained``    the noise floor, and the description of a residual left above it
  ``analysis``       the procedure, step by step (``analyse``), and the names callers need
  ``extended``       the extended model: parameter file with ``effects:``, current and tau_d for estimators
  ``report``         report.json, PNG plots, console summary
  ``cli``            the ``residuals`` executable

Read first: ``analysis`` (the steps), then ``free`` (what is corrected, and why).
"""
