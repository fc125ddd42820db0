"""The model-based load observer (the shipped estimator): a Kalman filter on Eqs 28-30 with load-step detection.

The rig's model (physics.md sections 6-7, worm_model.physics) with the state x = [θ, ω, i, τ_d]
(plus the tacho's ripple phase and the back-EMF error): the drive motor and the inertia are
linear and discretised exactly; the mesh and friction (Eq. 28) are the one nonlinearity, the
static map T_dist(ω, τ_d); the load is a slow random walk between steps, and a step detector
corrects the filter at once when the innovations say the load jumped. Gains follow from the
sensors' noise figures in the rig file, not from tuning.

Map:

``kalman``      LoadObserver, the streaming filter (one ``update`` per rig sample), its flags
                and restarts; read first
``static_map``  StaticLoadMap: T_dist(ω, τ_d) and its inverse per flank, on worm_model's Eq. 28
``discrete``    the state layout and the exact zero-order-hold discretisation per J_eff
``noise``       NoiseFigures (from the rig file's sensors) and LoadProcess: what the gains follow from
``glr``         StepDetector: the generalised likelihood ratio test for load steps
``convergence`` Convergence: whether the τ_d variance still settles after a start or a step (TRANSIENT)
``bounds``      the steady filter, its predicted noise, and the Cramér–Rao-type bounds
                (steady_state_bound, jump_bound)
``estimator``   ObserverEstimator: the registry's "observer" (quasi-static ``estimate``, ``stream``)
``streams``     the stream corrected for a model file's sensor errors and a calibration's bias

Units SI, angles in rad, fixed frame; τ_d [N·m] on the gear shaft, positive opposing positive
worm rotation. No ROS; numpy + scipy.
"""
from torque_estimator.estimation.observer.bounds import (equivalent_window, jump_bound, linearised, predicted_noise,
                                                         steady_filter, steady_state_bound)
from torque_estimator.estimation.observer.discrete import discretise
from torque_estimator.estimation.observer.estimator import ObserverEstimator
from torque_estimator.estimation.observer.kalman import (MAX_SKIP, RESTART_NIS, STANDSTILL, LoadObserver,
                                                         interval_measurement)
from torque_estimator.estimation.observer.noise import LoadProcess, NoiseFigures
from torque_estimator.estimation.observer.static_map import StaticLoadMap

__all__ = ["MAX_SKIP", "RESTART_NIS", "STANDSTILL", "LoadObserver", "LoadProcess", "NoiseFigures",
           "ObserverEstimator", "StaticLoadMap", "discretise", "equivalent_window", "interval_measurement",
           "jump_bound", "linearised", "predicted_noise", "steady_filter", "steady_state_bound"]
