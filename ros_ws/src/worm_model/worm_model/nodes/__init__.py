"""``model_node``: the gearbox's internal forces for every rig sample (a thin shell over
``worm_model.live``); ``joint_state_input``: a node's JointState input, its parameters declared once (model_node's
and torque_estimator's estimator_node)."""
