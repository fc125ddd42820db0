"""Speed control with load-torque feedforward: ``speed_controller`` (PI, anti-windup, Eq 28
feedforward, FeedforwardGate)."""
