"""What feeds the load forward: ``feedforward`` (which estimate may be fed forward, and the
FeedforwardGate's freshness rule), ``rig_feedforward`` (the estimator the rig runs beside its speed
loop, registered for worm_rig_driver's entry point). The speed PI itself runs at the rig
(worm_rig_driver.drive)."""
