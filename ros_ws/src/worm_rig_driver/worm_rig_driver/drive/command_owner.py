"""One master for the drive motor: the rig takes speed and drive commands from one publisher at a time.

A motor drive (CiA 402's single controlling device) and ros2_control (a command interface claimed by one
controller) give the motor to one claimant; two sources of commands would otherwise override each other
every few milliseconds. Rules, for claimants named by any hashable key (the rig's nodes use the
publishing node's name, found from the DDS GID rclpy hands with each message):

* the first claimant whose command arrives while nobody holds the claim takes it;
* the owner's commands are taken; any other's are refused and counted per claimant;
* the claim passes to the next claimant whose command arrives once the owner's last command is
  ``timeout`` [s] old (the rig's command_timeout: by then its watchdog has stopped the drive), or
  at once after :meth:`CommandOwner.release`.

Times are the caller's monotonic clock [s]. Plain Python, no ROS.
"""
from __future__ import annotations

from collections.abc import Hashable
from dataclasses import dataclass, field


@dataclass
class CommandOwner:
    """Which publisher holds the drive motor (module docstring)."""

    timeout: float  #: [s] silence of the owner after which another claimant may take the claim
    owner: Hashable | None = None
    last: float = float("-inf")  #: [s] when the owner's last command arrived
    refused: dict[Hashable, int] = field(default_factory=dict)  #: per refused claimant, its commands refused
    claims: int = 0  #: times the claim was taken (the first one included)

    def allows(self, publisher: Hashable, now: float) -> bool:
        """Whether a command from ``publisher`` at ``now`` may drive the motor (claims and counts nothing)."""
        return publisher == self.owner or self.owner is None or now - self.last >= self.timeout

    def offer(self, publisher: Hashable, now: float) -> bool:
        """A command from ``publisher`` arrived at ``now``: True if it is the owner's (or takes the claim)."""
        if not self.allows(publisher, now):
            self.refused[publisher] = self.refused.get(publisher, 0) + 1
            return False
        if publisher != self.owner:
            self.owner = publisher
            self.claims += 1
        self.last = now
        return True

    def release(self) -> None:
        """Free the claim at once: the next claimant's command takes it."""
        self.owner = None
        self.last = float("-inf")

    @property
    def refused_total(self) -> int:
        return sum(self.refused.values())


__all__ = ["CommandOwner"]
