"""Closing the loop with measured data (issue 7, physics.md section 9).

Modules (plain Python, no ROS):
  data      the input: a ``worm_rig_data`` CSV (schema, reader, writer: worm_model.rig_data.schema) or a bag
            via worm_rig_driver
  model     the drive current the declared model predicts, plus effect channels; the transmission
            error ratio*theta_worm - theta_gear when the data has a gear encoder
  free      which rig parameters a fit may change (the rig file's ``free:`` list)
  effects   candidate effects as plug-ins (Protocol + registry EFFECTS)
  analysis  held-out split, fits (current; transmission error), ranking of candidates, significance,
            selection loop
  extended  the extended model: parameter file with ``effects:``, current and tau_d for estimators
  report    report.json, PNG plots, console summary
  cli       the ``residuals`` executable
"""
