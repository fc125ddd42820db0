"""What the controller node decides: ``feedforward`` (which estimate may be fed forward, and the
FeedforwardGate's freshness rule). The speed PI itself runs at the rig (worm_rig_driver.drive)."""
