"""``model_node``: the gearbox's internal forces for every rig sample (a thin shell over
``worm_model.live``)."""
