"""effects: the simulator's face of the effects the model lacks (physics.md section 9), and the gearbox's aging.

The effects, their parameters (unit, default, meaning) and the ``worm_rig_effects`` file are
worm_model.effects' (the one vocabulary); here is what the simulator does with them, its forward
hooks. Each effect is a small class behind one protocol (``hooks.Effect``), attached to its declared
name (``hooks.simulates``) and found in the registry ``EFFECTS`` (the way rosbags finds storage
plug-ins in ``STORAGE_PLUGINS``). It reads its parameters in ``self.p`` and implements only the
hooks it needs:

  worm_torque   extra torque on the worm shaft, a function of the shaft state
  gear_torque   extra torque on the gear shaft
  friction      a modified mesh friction coefficient mu
  inertia       the true shaft inertias (they differ from the rig file's)
  backlash      the gear-side clearance of the mesh (the plant's dead zone)
  drive_voltage what the H-bridge really applies for a requested voltage
  advance       its own state (oil temperature) over one step
  sense         what the sensors read (gain, offset, PWM ripple), before the ADC
  observe       its own state, for the ground truth

Float twins (the scalar fast path for one rig, sim/scalar_plant.py): the hooks that run every step
have a twin ``<hook>_float`` taking and returning plain floats (shaft state as six positional floats,
see ``hooks.FLOAT_SHAFT``), computed with the same floating-point operations as the array hook, so
that both paths agree to round-off. An effect without the twin of a hook it changes still works: the
simulator then steps that rig with the vectorised plant (scalar_plant.float_hooks_missing).

Aging (``wear``, ``lubricant_loss``, ``seal_drag``): effects that evolve over the gearbox's life
(hours run) or step at a given rig time, so that a health monitor is measured on runs whose truth
is known. At their defaults they leave the gearbox as new.

The simulator switches effects on from a YAML file (worm_model.effects.load_effects); the model
(the rig file) is not told: the effects are *undeclared*, the test bed for closing the loop between
model and measurements. The hooks are the simulator's own formulas, stepped sample by sample (the
oil's law and the mesh heat are the model's, worm_model.effects.oil and .heat); the residual
analysis's regressors are written apart, so that it is judged on data it did not make.

Conventions (those of plant.py; SI units, angles in rad):
  * worm quantities in the fixed frame, + along + worm rotation;
  * gear quantities about the gear's own axis but worm-referenced: + is the gear
    rotation that goes with + worm rotation, so omega_gear = ratio * omega_worm
    in contact; theta_gear is the gear's own angle;
  * worm_torque: + drives + worm rotation (a drag is -c sign(omega_worm));
  * gear_torque: + OPPOSES + gear rotation, like the load torque tau_load (a drag
    is +c sign(omega_gear)).

Map (dependencies point up this list):

============  ==============================================================
``hooks``     what an effect sees (``ShaftState``, ``SenseContext``), the protocol,
              ``EffectBase``, ``simulates``
``drags``     bearing and seal Coulomb drag, viscous and churning drag
``mesh``      mu's speed, load and oil-temperature laws; backlash; inertia errors
``ripples``   worm and gear runout, the tooth pass, motor cogging
``sensing``   sensor gain and offset errors, the PWM
``aging``     wear, lubricant loss, a dragging seal
``registry``  ``EFFECTS``: name -> hook class (a view of worm_model.effects' registry)
``stack``     ``EffectStack``: one simulator's live effects, built from an
              ``EffectsConfig`` and composed hook by hook
``cli``       the ``worm_effects`` executable (``__main__``: ``python -m`` runs it)
============  ==============================================================

Read first: ``hooks`` (what an effect may change), then ``mesh.OilTemperature`` (an effect with state).
"""
from worm_model.effects import FORMAT_NAME, FORMAT_VERSION, EffectsConfig, as_config, load_effects

from worm_rig_driver.sim.effects.hooks import (FLOAT_SHAFT, HOOKS, SIGNALS, Effect, EffectBase, SenseContext,
                                               ShaftState, simulates)
from worm_rig_driver.sim.effects.registry import EFFECTS
from worm_rig_driver.sim.effects.stack import EffectStack
from worm_rig_driver.sim.effects.cli import TEMPLATE_MARK, describe, main, template

__all__ = ["EFFECTS", "FLOAT_SHAFT", "FORMAT_NAME", "FORMAT_VERSION", "HOOKS", "SIGNALS", "TEMPLATE_MARK", "Effect",
           "EffectBase", "EffectStack", "EffectsConfig", "SenseContext", "ShaftState", "as_config", "describe",
           "load_effects", "main", "simulates", "template"]
