"""The load estimate of a robot's worm-geared joints, from its sensor_msgs/JointState (no ROS).

``settings``    per-joint estimator settings from estimator_node's parameters (joint_names and the
                lists parallel to it: rig, model and calibration files, voltage topics), and which
                methods a JointState can feed (no voltage: not the observer, unless given one)
``estimators``  JointEstimators: worm_model.rig_data.joint_states' reader and one LiveEstimator per
                joint, with their counts for /diagnostics
"""
