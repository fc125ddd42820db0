"""JointEstimators: a robot's JointState in, one load estimate per joint out (what estimator_node runs on it).

Each message goes through worm_model.rig_data.joint_states.JointStateReader (joints by name,
motor or output side, effort as current or motor torque, stamps and refusals counted), and each
joint's accepted sample to that joint's LiveEstimator (built by estimation.settings from the
joint's settings: settings.JointSetup), with the joint's seq, so a message lost or refused is a gap
the estimator bridges (LiveEstimator.follow). A joint's conversion uses the rig its LiveEstimator
runs (the rig file, or the model file's identified rig): the same ratio and K_t as its
compensation. Joints with equal settings share one built estimator (the maps are read-only;
each LiveEstimator keeps its own state).

Cost: a quasi-static map (knn, extended_model) costs about as much for one sample as for a few
hundred, and its estimate is read only where it is published. So every sample goes through each
joint's filters (LiveEstimator.filter: the estimate's state, every sample), and the map runs when
the caller asks for estimates (``estimate=True``: estimator_node every ``publish_every``-th
message), once for all the joints that share it (live.estimate_filtered); the values are those
LiveEstimator.update gives for the same samples. A streaming estimator (the observer) follows
every sample itself.

No ROS; the caller hands over the message's fields.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from worm_model.rig_data.estimate import Estimate
from worm_model.rig_data.joint_states import JointConversion, JointStateReader

from torque_estimator.estimation.base import EstimateFlags
from torque_estimator.estimation.live import Filtered, LiveEstimator, estimate_filtered
from torque_estimator.estimation.settings import BuiltEstimator, build_estimator
from torque_estimator.joints.settings import JointSetup

#: the flags counted per joint for /diagnostics
COUNTED_FLAGS = tuple(flag for flag in EstimateFlags if flag)


class JointEstimators:
    """One LiveEstimator per joint of a JointState (module docstring).

    Args:
        setups: the joints (settings.joint_setups), in the order estimates are returned.
        sample_period: [s] between the JointState messages.
        joint_side: "motor" or "output" (worm_model.rig_data.joint_states).
        effort_is: "current" or "motor_torque".

    Raises:
        CalibrationError, ParameterError, ValueError: a joint's estimator cannot be built (build_estimator).
    """

    def __init__(self, setups: Sequence[JointSetup], sample_period: float, joint_side: str = "output",
                 effort_is: str = "current") -> None:
        self.setups = list(setups)
        cache: dict[str, BuiltEstimator] = {}
        self.built: list[BuiltEstimator] = []
        for setup in self.setups:
            key = repr(setup.settings)
            if key not in cache:
                cache[key] = build_estimator(setup.settings)
            self.built.append(cache[key])
        self.live: list[LiveEstimator] = [b.live(sample_period) for b in self.built]
        self.reader = JointStateReader([JointConversion.from_rig(s.name, b.rig, joint_side, effort_is)
                                        for s, b in zip(self.setups, self.built)], sample_period)
        self.names = [s.name for s in self.setups]
        self.flag_counts = [dict.fromkeys((f.name for f in COUNTED_FLAGS), 0) for _ in self.setups]
        #: per joint, the last message's (flags, tau_d [N m] or None where not computed), (None, None) where the
        #: message gave the joint no sample: what the standard outputs judge every sample by
        self.judged: list[tuple[int | None, float | None]] = [(None, None)] * len(self.setups)
        #: per joint, whether its estimator started again at the last message's sample (a new session)
        self.restarted: list[bool] = [False] * len(self.setups)
        self._flag_bits = [(int(f), f.name) for f in COUNTED_FLAGS]

    @property
    def max_loads(self) -> list[float]:
        """Per joint, 1.5 x its rig file's max_load_torque [N m] (the standard outputs' plausibility bound)."""
        return [1.5 * b.rig.max_load_torque for b in self.built]

    def update(self, stamp_ns: int, names: Sequence[str], position: Sequence[float], velocity: Sequence[float],
               effort: Sequence[float], voltage: Mapping[str, float] | None = None, estimate: bool = True
               ) -> list[tuple[int, Estimate] | None]:
        """One message (header stamp [ns], its arrays; ``voltage`` [V] by joint name where known): per joint,
        (seq, estimate) of its sample, or None where the message gave it none (refused: the reader counts
        why) or ``estimate`` is False and the joint's estimator is a map (filtered only: module docstring)."""
        out: list[tuple[int, Estimate] | None] = []
        filtered: dict[int, tuple[int, Filtered]] = {}
        judged = self.judged
        for k, sample in enumerate(self.reader.read(stamp_ns, names, position, velocity, effort, voltage)):
            out.append(None)
            judged[k] = (None, None)
            self.restarted[k] = False
            if sample is None:
                continue
            live = self.live[k]
            restarts = live.restarts
            if live.quasi_static:
                f = live.filter(sample.omega_worm, sample.current_drive, sample.theta_worm, sample.seq)
                judged[k] = (f.flags, None)  # the map's own flags and torque: where it runs (below)
                self.restarted[k] = live.restarts != restarts
                if estimate:
                    filtered[k] = (sample.seq, f)
                continue
            voltage_k = sample.voltage_drive if math.isfinite(sample.voltage_drive) else None
            out[k] = (sample.seq, self._count(k, live.update(sample.omega_worm, sample.current_drive,
                                                             voltage_drive=voltage_k, theta_worm=sample.theta_worm,
                                                             seq=sample.seq)))
            judged[k] = (out[k][1].flags, out[k][1].torque)
            self.restarted[k] = live.restarts != restarts
        if filtered:
            groups: dict[int, list[int]] = {}
            for k in filtered:
                groups.setdefault(id(self.built[k].estimator), []).append(k)
            for members in groups.values():
                estimates = estimate_filtered(self.built[members[0]].estimator, [filtered[k][1] for k in members])
                for k, est in zip(members, estimates):
                    est = self.live[k].judge(est)
                    out[k] = (filtered[k][0], self._count(k, est))
                    judged[k] = (est.flags, est.torque)
        return out

    def _count(self, k: int, est: Estimate) -> Estimate:
        if est.flags:
            counts = self.flag_counts[k]
            for bit, name in self._flag_bits:
                if est.flags & bit:
                    counts[name] += 1
        return est

    def report(self) -> dict[str, int]:
        """Per joint (``<joint>.<count>``): samples taken, refusals by reason, seq gaps bridged and the
        samples in them, stream restarts, flagged estimates by flag (of the estimates computed); and the
        malformed messages."""
        values: dict[str, int] = {"messages": self.reader.messages,
                                  "malformed_messages": self.reader.malformed_messages}
        for k, name in enumerate(self.names):
            live = self.live[k]
            values[f"{name}.samples"] = self.reader.samples(name)
            values.update({f"{name}.{reason}": n for reason, n in self.reader.refused(name).items()})
            values.update({f"{name}.seq_gaps": live.gaps, f"{name}.samples_lost": live.lost,
                           f"{name}.stream_restarts": live.restarts})
            values.update({f"{name}.{flag}": n for flag, n in self.flag_counts[k].items()})
        return values


__all__ = ["COUNTED_FLAGS", "JointEstimators"]
