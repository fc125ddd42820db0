"""Estimators of the load torque tau_d, and what builds and runs them.

``base``            the interface: inputs, outputs, EstimateFlags; the streaming and angle protocols
``registry``        the methods by name: factory, the options each reads (estimator_node's parameters)
``settings``        EstimatorSettings and build_estimator: what estimator_node, replay, ``estimate`` and
                    the rig feedforward build their estimator from, one way
``live``            LiveEstimator: the per-sample front end (filters in front of a quasi-static map, or
                    a stream fed every sample)
``observer``        the shipped estimator: a Kalman filter on the rig's model with a load-step detector
                    (a folder: its own map)
``momentum``        the momentum observer: the load from current and speed only, no voltage (a folder: its
                    own map)
``knn``             the paper's k-NN map over a calibration
``extended_model``  inverts the identified model's quasi-static current
``database``        the calibration database the maps read, and its file format
``quasi_static``    the inertia's share taken out of the current (LiveEstimator's compensation)
``calibration_bias``  the model's steady error read off a calibration (added by the observer and momentum)
``branches``        which of a self-locking drive's two candidate loads is the load: the declared prior and
                    the motion (reversals, stops, holds)
"""
