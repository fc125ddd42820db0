"""The estimators over recorded data, no DDS: ``estimate`` (any estimator over a CSV log or a bag,
scored against its tau_load) and ``replay`` (model_node's and estimator_node's cores over a bag,
compared with the live outputs recorded in it). ``moves`` scores a start-stop run move by move (lifting,
lowering) for ``estimate``.
"""
