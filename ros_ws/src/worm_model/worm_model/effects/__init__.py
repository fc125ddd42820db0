"""effects: the one vocabulary of the effects the paper's model lacks, their file, and the physics the model owns.

An effect is declared once (name, summary, parameters with unit, default, range and meaning); the
simulator's forward hooks (worm_rig_driver.sim.effects), the residual analysis's regressors
(worm_model.residuals.effects) and the health monitor's thermal model (worm_model.health) are faces
that read the declaration. Each face keeps its own formulas (the simulator steps the truth sample by
sample; the analysis fits closed forms over a run), so that the analysis is judged on data it did not
make; what they share is the names, parameters, units and defaults, the file, and the two laws below.

Map (dependencies point up this list):

===============  ==============================================================
``parameters``   how a parameter is declared (``Parameter``), the units a file may
                 use, the range checks, the check of one value
``registry``     ``Declaration``; ``register`` an effect with its faces, ``implement``
                 one face; the live views ``VOCABULARY`` and ``Face``
``vocabulary``   the built-in effects, declared (physics.md section 9, the PWM, aging)
``file_format``  the ``worm_rig_effects`` file: ``EffectsConfig``, ``load_effects``
``oil``          the oil temperature law (first order, exact step)
``heat``         the mesh heat, power in at the worm less power out at the gear
===============  ==============================================================

Read first: ``vocabulary`` (what the effects are), then ``registry`` (how a side finds them).
Adding an effect: docs/design.md, "Adding an effect".
"""
import worm_model.effects.vocabulary  # noqa: F401  (declares the built-in effects)
from worm_model.effects.file_format import FORMAT_NAME, FORMAT_VERSION, EffectsConfig, as_config, load_effects
from worm_model.effects.parameters import Parameter
from worm_model.effects.registry import VOCABULARY, Declaration, Face, implement, register, unregister

__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "VOCABULARY", "Declaration", "EffectsConfig", "Face", "Parameter",
           "as_config", "implement", "load_effects", "register", "unregister"]
