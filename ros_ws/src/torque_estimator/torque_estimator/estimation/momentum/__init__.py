"""The momentum observer: τ_d from the drive current and the worm speed (and the encoder angle when there is one),
without the voltage, for drives that report only current (or a torque from it) and velocity.

Map:

``observer``   MomentumObserver, the streaming filter (De Luca's generalised-momentum residual on the
               rig's model, in its Kalman form, with the load observer's step detector); read first
``discrete``   its state and its motion over one period with the current as the input; the bandwidth
               option's load variance
``bounds``     what any estimator can do from these sensors: the steady filter, its noise, the
               Cramér–Rao bound on a step, and the noise floor of a fast linear estimator
``estimator``  MomentumEstimator: the registry's "momentum" (the load observer's face, this filter)

It reuses the load observer's parts (estimation/observer/): the static map T_dist(ω, τ_d) and its
inverse per flank, the noise figures, the step detector and the stream wrappers. Units SI, angles in
rad, fixed frame; τ_d [N·m] on the gear shaft, positive opposing positive worm rotation. No ROS.
"""
from torque_estimator.estimation.momentum.bounds import (jump_bound, linear_noise_bound, predicted_noise,
                                                         steady_filter, steady_variance)
from torque_estimator.estimation.momentum.estimator import DEFAULT_FALSE_ALARM, MomentumEstimator
from torque_estimator.estimation.momentum.observer import DEFAULT_BANDWIDTH, MomentumObserver

__all__ = ["DEFAULT_BANDWIDTH", "DEFAULT_FALSE_ALARM", "MomentumEstimator", "MomentumObserver", "jump_bound",
           "linear_noise_bound", "predicted_noise", "steady_filter", "steady_variance"]
