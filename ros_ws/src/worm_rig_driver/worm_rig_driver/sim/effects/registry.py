"""The registry: every effect the simulator knows, by name (as rosbags finds its storage plug-ins).

A live view of worm_model.effects' registry: the declared effects whose hooks are attached (:func:`hooks.simulates`
in the modules below, or ``worm_model.effects.register(..., simulator=cls)`` from outside), in the vocabulary's order.
"""
from __future__ import annotations

from worm_model.effects import Face

# the modules whose hook classes attach themselves on import
from worm_rig_driver.sim.effects import aging, drags, mesh, ripples, sensing  # noqa: F401
from worm_rig_driver.sim.effects.hooks import FACE

#: effect name -> hook class (EffectBase subclass)
EFFECTS = Face(FACE)
