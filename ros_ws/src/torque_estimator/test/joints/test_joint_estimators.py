"""A robot's JointState gives each joint exactly the estimate its rig samples give (same method, same
samples), whatever the order of the names, the side the positions are on and the effort's unit; a method
that needs the voltage is refused without one, with the parameter named."""
from __future__ import annotations

import math

import numpy as np
import pytest

from worm_model.physics.parameters import load_rig
from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS, SpeedController
from worm_rig_driver.sim.simulated_rig import SimulatedRig

from torque_estimator.estimation.base import EstimateFlags
from torque_estimator.estimation.settings import EstimatorSettings, build_estimator
from torque_estimator.joints.estimators import JointEstimators
from torque_estimator.joints.settings import JOINT_STATE_METHOD, joint_setups, per_joint

RIG = load_rig(None)
NS = 1_000_000  # [ns] per ms


def simulated_samples(samples: int = 1500) -> dict[str, np.ndarray]:
    """Two rigs (seeds) held at 150 and -100 rad/s, a load step on the first at 0.5 s: every sample's inputs."""
    sim = SimulatedRig(RIG, n=2, seed=3)
    controller = SpeedController(RIG, DEFAULT_GAINS, n=2)
    out = {k: np.empty((samples, 2)) for k in ("omega_worm", "current_drive", "theta_worm", "voltage_drive")}
    for k in range(samples):
        sim.command(load_torque=np.array([0.15 if k >= 500 else 0.0, 0.05]))
        m = sim.sample()
        for name in out:
            out[name][k] = getattr(m, name)
        sim.command(voltage_drive=controller.update(sim.sample_period, np.array([150.0, -100.0]), m.omega_worm).voltage)
    return out


def test_a_joint_state_estimates_as_the_rig_samples_do() -> None:
    data = simulated_samples()
    parameters = {"method": JOINT_STATE_METHOD}
    joints = JointEstimators(joint_setups(parameters, ["hip", "knee"]), 0.001, joint_side="output",
                             effort_is="motor_torque")
    ratio, k_t = RIG.gearbox.ratio, RIG.drive_motor.torque_constant
    built = build_estimator(EstimatorSettings(JOINT_STATE_METHOD))
    direct = [built.live(0.001) for _ in range(2)]
    worst = 0.0
    for k in range(len(data["omega_worm"])):
        # as a robot publishes it: other joints too, names in its own order, the gear side, effort as K_t i
        order = [1, 0]  # knee first
        names = ["wrist", *("hip", "knee")[::-1]]
        position = [0.0, *(data["theta_worm"][k, j] * ratio for j in order)]
        velocity = [1.0, *(data["omega_worm"][k, j] * ratio for j in order)]
        effort = [2.0, *(data["current_drive"][k, j] * k_t for j in order)]
        got = joints.update(k * NS, names, position, velocity, effort)
        for j in range(2):
            want = direct[j].update(float(data["omega_worm"][k, j]), float(data["current_drive"][k, j]),
                                    theta_worm=float(data["theta_worm"][k, j]), seq=k)
            seq, est = got[j]
            assert seq == k
            worst = max(worst, abs(est.torque - want.torque))
            assert est.flags == want.flags
    assert worst < 1e-9  # the unit conversions' round-off only
    report = joints.report()
    assert report["hip.samples"] == report["knee.samples"] == 1500 and report["hip.absent"] == 0


def test_a_lost_message_is_a_gap_the_estimator_bridges() -> None:
    joints = JointEstimators(joint_setups({"method": JOINT_STATE_METHOD}, ["j"]), 0.001, "motor", "current")
    for k in (0, 1, 2, 5, 6):  # 3 and 4 never arrived
        joints.update(k * NS, ["j"], [], [100.0], [0.5])
    assert joints.update(7 * NS, ["j"], [], [math.nan], [0.5]) == [None]  # refused, counted: not estimated from
    report = joints.report()
    assert (report["j.seq_gaps"], report["j.samples_lost"], report["j.not_finite"], report["j.samples"]) == (1, 2, 1, 5)


def test_per_joint_files_and_the_voltage_rule() -> None:
    assert per_joint("rig_files", [], ["a", "b"], "x.yaml") == ["x.yaml", "x.yaml"]
    with pytest.raises(ValueError, match=r"parameter rig_files: 1 entries for 2 joints"):
        per_joint("rig_files", ["a.yaml"], ["a", "b"])
    setups = joint_setups({"method": "knn", "calibration_file": "c.json"}, ["a", "b"],
                          files={"rig_files": ["a.yaml", "b.yaml"]})
    assert [(s.settings.rig_file, s.settings.calibration_file) for s in setups] == [("a.yaml", "c.json"),
                                                                                    ("b.yaml", "c.json")]
    with pytest.raises(ValueError, match=r"method='observer' reads the drive voltage .* \(none for \['b'\]\)"):
        joint_setups({"method": "observer"}, ["a", "b"], voltage_topics=["a/voltage", ""])
    assert [s.voltage_topic for s in joint_setups({"method": "observer"}, ["a"], voltage_topics=["v"])] == ["v"]
    with pytest.raises(ValueError, match="names a joint twice"):
        joint_setups({}, ["a", "a"])


def test_a_stop_is_held_as_long_when_only_published_messages_are_estimated() -> None:
    """estimator_node maps a JointState only every publish_every-th message; the standstill hold counts the
    stream's samples, not the estimates: a stop of 0.5 s is held, ends, and lets its uncertainty grow as when
    every message is estimated (within one publishing period: 5 ms)."""
    every_nth, samples = 5, 1200
    sim = SimulatedRig(RIG, n=1, seed=5)
    controller = SpeedController(RIG, DEFAULT_GAINS, n=1)
    joints = JointEstimators(joint_setups({"method": JOINT_STATE_METHOD}, ["knee"]), 0.001, joint_side="output",
                             effort_is="current")
    direct = build_estimator(EstimatorSettings(JOINT_STATE_METHOD)).live(0.001)
    ratio = RIG.gearbox.ratio
    standing: dict[str, list[int]] = {"published": [], "every": []}
    sigma: dict[str, dict[int, float]] = {"published": {}, "every": {}}
    for k in range(samples):
        set_point = 0.0 if 300 <= k < 800 else 100.0  # [rad/s] a stop of 0.5 s between two moves
        sim.command(load_torque=np.array([0.05]))
        m = sim.sample()
        omega, current, theta = float(m.omega_worm[0]), float(m.current_drive[0]), float(m.theta_worm[0])
        want = direct.update(omega, current, theta_worm=theta, seq=k)
        published = k % every_nth == every_nth - 1
        got = joints.update(k * NS, ["knee"], [theta * ratio], [omega * ratio], [current], estimate=published)
        if published:
            for name, est in (("published", got[0][1]), ("every", want)):
                if est.flags & EstimateFlags.STANDSTILL:
                    standing[name].append(k)
                    sigma[name][k] = est.uncertainty
        sim.command(voltage_drive=controller.update(sim.sample_period, np.array([set_point]), m.omega_worm).voltage)
    assert standing["every"] and 300 < standing["every"][0] < 400 and standing["every"][-1] > 800
    for end in (0, -1):  # the hold's start and its end, one publishing period apart at most
        assert abs(standing["published"][end] - standing["every"][end]) <= every_nth, standing
    first, last = standing["every"][0] + every_nth, standing["every"][-1] - every_nth
    growth = {name: s[last] ** 2 - s[first] ** 2 for name, s in sigma.items()}  # [(N m)^2] the held variance's rise
    assert growth["every"] > 0 and growth["published"] == pytest.approx(growth["every"], rel=1e-6), growth
