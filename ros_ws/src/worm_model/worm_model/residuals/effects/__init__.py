"""effects: the residual analysis's face of the effects the model lacks (physics.md section 9), as regressors.

The effects, their names and parameters (unit, default, meaning) are worm_model.effects' (the one
vocabulary); here is how the analysis sees each in the data: as channels of the model's current
(shapes, one column per linear coefficient) or of the transmission error, with a grid for what it is
not linear in. The regressors are the analysis's own formulas (closed forms over a run, evaluated on
the *declared* model), written apart from the simulator's forward hooks so that the analysis is judged
on data it did not make; the oil law and the mesh heat are the model's (worm_model.effects.oil, .heat).

Map (dependencies point up this list):

==============  ==============================================================
``base``        the protocol (``Effect``), ``Coefficient``, ``GridParameter``,
                ``regresses``; channels and regressors of fitted effects
``regression``  drags, mu's speed and load laws, sensor gain and offset, inertia
``thermal``     the oil's warming scaling mu (measured, or the oil law in closed form)
``ripples``     worm and gear runout, the tooth pass, motor cogging (periodic)
``backlash``    the clearance, seen in the transmission error
``pwm``         the PWM ripple the ADC samples at a fixed phase
==============  ==============================================================

``EFFECTS`` (name -> regressor, a view of worm_model.effects' registry in the vocabulary's order) is
what the analysis screens. Read first: ``base``, then ``regression.BearingCoulomb`` (the simplest).
"""
from worm_model.residuals.effects import backlash, pwm, regression, ripples, thermal  # noqa: F401  (they attach)
from worm_model.residuals.effects.backlash import Backlash, gap_crossing
from worm_model.residuals.effects.base import (FACE, Coefficient, Effect, GridParameter, Shapes, channels_of,
                                               mask_shapes, mesh_load, regresses, regressors)
from worm_model.residuals.effects.pwm import (CURRENT_HOLD_DELAY, PWM_FREQUENCY, Pwm, firmware_sampling_phase,
                                              sampled_ripple)
from worm_model.residuals.effects.thermal import OilTemperature, first_order_lag, mesh_heat

from worm_model.effects import Face

#: effect name -> regressor (the analysis's candidates)
EFFECTS = Face(FACE)

__all__ = ["CURRENT_HOLD_DELAY", "EFFECTS", "PWM_FREQUENCY", "Backlash", "Coefficient", "Effect", "GridParameter",
           "OilTemperature", "Pwm", "Shapes", "channels_of", "firmware_sampling_phase", "first_order_lag",
           "gap_crossing", "mask_shapes", "mesh_heat", "mesh_load", "regresses", "regressors", "sampled_ripple"]
