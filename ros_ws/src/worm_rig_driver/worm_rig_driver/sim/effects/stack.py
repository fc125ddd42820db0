"""The live effects of one simulator, composed hook by hook."""
from __future__ import annotations

import numpy as np

from worm_model.effects import EffectsConfig
from worm_model.errors import EffectsError
from worm_model.physics.parameters import Rig

from worm_rig_driver.sim.effects.hooks import HOOKS, EffectBase, SenseContext, ShaftState
from worm_rig_driver.sim.effects.registry import EFFECTS


class EffectStack:
    """The live effects of one simulator, composed hook by hook (sums of torques, chained mu, ...).

    With no effect on a hook, the plant skips it entirely (``has_*`` flags), so the
    pure model costs nothing extra.
    """

    def __init__(self, effects: list[EffectBase]) -> None:
        self.effects = effects
        by_hook = {hook: [e for e in effects if hook in type(e).hooks()] for hook in HOOKS}
        self._worm = by_hook["worm_torque"]
        self._gear = by_hook["gear_torque"]
        self._friction = by_hook["friction"]
        self._voltage = by_hook["drive_voltage"]
        self._advance = by_hook["advance"]
        self._sense = by_hook["sense"]
        self._observe = by_hook["observe"]
        self._inertia = by_hook["inertia"]
        self._dissipative = [e for e in effects if e.dissipative]
        self.has_worm_torque = bool(self._worm)
        self.has_gear_torque = bool(self._gear)
        self.has_friction = bool(self._friction)
        self.has_voltage = bool(self._voltage)
        self.has_sense = bool(self._sense)
        self.needs_heat = bool(self._advance)
        self.backlash = float(sum(e.backlash() for e in by_hook["backlash"]))

    @classmethod
    def build(cls, config: EffectsConfig, n: int, rig: Rig) -> "EffectStack":
        """The live effects (each with its own state) of ``config`` for a simulator of n rigs.

        Raises:
            EffectsError: an effect the vocabulary declares but the simulator has no hooks for.
        """
        missing = [name for name in config.effects if name not in EFFECTS]
        if missing:
            raise EffectsError(config.source or "<effects>", f"effects.{missing[0]}",
                               f"the simulator has no hooks for this effect (it has: {', '.join(EFFECTS)})")
        return cls([EFFECTS[name](params, n, rig) for name, params in config.effects.items()])

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(e.name for e in self.effects)

    def worm_torque(self, s: ShaftState) -> np.ndarray:
        """Sum of the worm-shaft torques [N m], + along + worm rotation."""
        total = self._worm[0].worm_torque(s)
        for e in self._worm[1:]:
            total = total + e.worm_torque(s)
        return total

    def gear_torque(self, s: ShaftState) -> np.ndarray:
        """Sum of the gear-shaft torques [N m], + opposing + gear rotation."""
        total = self._gear[0].gear_torque(s)
        for e in self._gear[1:]:
            total = total + e.gear_torque(s)
        return total

    def friction(self, mu: np.ndarray, v_sliding: np.ndarray, s: ShaftState) -> np.ndarray:
        for e in self._friction:
            mu = e.friction(mu, v_sliding, s)
        return mu

    def inertia(self, worm: float, gear: float) -> tuple[float, float]:
        for e in self._inertia:
            worm, gear = e.inertia(worm, gear)
        return worm, gear

    def drive_voltage(self, voltage: np.ndarray, supply: float) -> np.ndarray:
        for e in self._voltage:
            voltage = e.drive_voltage(voltage, supply)
        return voltage

    def heat(self, s: ShaftState) -> np.ndarray:
        """Power [W] the dissipative shaft effects turn into heat inside the gearbox (>= 0)."""
        power = np.zeros_like(s.omega_worm)
        for e in self._dissipative:
            power = power - e.worm_torque(s) * s.omega_worm + e.gear_torque(s) * s.omega_gear
        return power

    def advance(self, dt: float, heat: np.ndarray) -> None:
        for e in self._advance:
            e.advance(dt, heat)

    def sense(self, signals: dict[str, np.ndarray], context: SenseContext) -> None:
        for e in self._sense:
            e.sense(signals, context)

    def observe(self) -> dict[str, np.ndarray]:
        found: dict[str, np.ndarray] = {}
        for e in self._observe:
            found.update(e.observe())
        return found
