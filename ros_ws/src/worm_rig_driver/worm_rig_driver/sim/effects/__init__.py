"""effects: what the paper's model lacks (physics.md section 9), and the gearbox's aging, as plug-ins of the simulator.

Each effect is a small class behind one protocol (``hooks.Effect``) and is found by its name in the
registry ``EFFECTS`` (the way rosbags finds storage plug-ins in ``STORAGE_PLUGINS``). An effect
declares its parameters (unit, default, meaning) and implements only the hooks it needs:

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

The simulator switches effects on from a YAML file (``config.load_effects``); the model
(worm_model) is not told: the effects are *undeclared*, the test bed for closing the loop between
model and measurements.

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
``hooks``     how an effect declares its parameters (units, checks), what it sees
              (``ShaftState``, ``SenseContext``), the protocol, ``EffectBase``
``drags``     bearing and seal Coulomb drag, viscous and churning drag
``mesh``      mu's speed, load and oil-temperature laws; backlash; inertia errors
``ripples``   worm and gear runout, the tooth pass, motor cogging
``sensing``   sensor gain and offset errors, the PWM
``aging``     wear, lubricant loss, a dragging seal
``registry``  ``EFFECTS``: name -> class
``stack``     ``EffectStack``: one simulator's live effects, composed hook by hook
``config``    the ``worm_rig_effects`` file: the format, which effects are on
              (``EffectsConfig``, ``load_effects``)
``cli``       the ``worm_effects`` executable (``__main__``: ``python -m`` runs it)
============  ==============================================================

Read first: ``hooks`` (what an effect may change), then ``mesh.OilTemperature`` (an effect with state).
"""
from worm_rig_driver.sim.effects.config import (FORMAT_NAME, FORMAT_VERSION, RIG_FORMAT_NAME, EffectsConfig, as_config,
                                                load_effects)
from worm_rig_driver.sim.effects.hooks import (CHECKS, FLOAT_SHAFT, HOOKS, PLAUSIBLE, SIGNALS, UNITS, Effect,
                                               EffectBase, Parameter, SenseContext, ShaftState)
from worm_rig_driver.sim.effects.registry import EFFECTS
from worm_rig_driver.sim.effects.stack import EffectStack
from worm_rig_driver.sim.effects.cli import TEMPLATE_MARK, describe, main, template

__all__ = ["CHECKS", "EFFECTS", "FLOAT_SHAFT", "FORMAT_NAME", "FORMAT_VERSION", "HOOKS", "PLAUSIBLE", "RIG_FORMAT_NAME",
           "SIGNALS", "TEMPLATE_MARK", "UNITS", "Effect", "EffectBase", "EffectStack", "EffectsConfig", "Parameter",
           "SenseContext", "ShaftState", "as_config", "describe", "load_effects", "main", "template"]
