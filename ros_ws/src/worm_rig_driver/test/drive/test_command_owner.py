"""drive.command_owner: one claimant drives the motor; the claim passes after the owner's silence or a release."""
from __future__ import annotations

from worm_rig_driver.drive.command_owner import CommandOwner


def test_the_first_claimant_holds_the_motor_and_the_others_are_counted() -> None:
    owner = CommandOwner(timeout=0.1)
    assert owner.offer("controller", 0.0)
    assert not owner.offer("stray", 0.01) and not owner.offer("stray", 0.02) and not owner.offer("other", 0.03)
    assert owner.offer("controller", 0.05)
    assert not owner.offer("stray", 0.149)  # 0.099 s after the owner's last command: still the owner's
    assert owner.owner == "controller" and owner.refused == {"stray": 3, "other": 1} and owner.refused_total == 4


def test_the_claim_passes_after_the_owners_silence_and_at_once_on_release() -> None:
    owner = CommandOwner(timeout=0.1)
    owner.offer("controller", 0.0)
    assert owner.offer("stray", 0.1) and owner.owner == "stray"  # the owner was silent for command_timeout
    assert not owner.offer("controller", 0.15)  # the former owner is now the one refused
    owner.release()
    assert owner.offer("controller", 0.16) and owner.owner == "controller" and owner.claims == 3


def test_allows_asks_without_claiming_or_counting() -> None:
    owner = CommandOwner(timeout=0.1)
    assert owner.allows("stray", 0.0) and owner.owner is None and owner.claims == 0
    owner.offer("controller", 0.0)
    assert not owner.allows("stray", 0.05) and owner.refused == {}
    assert owner.allows("controller", 0.05) and owner.allows("stray", 0.1) and owner.owner == "controller"
