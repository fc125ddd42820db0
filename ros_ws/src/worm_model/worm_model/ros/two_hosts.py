"""Two hosts on one machine, for tests and benchmarks that split a graph between a rig computer and a
workstation and cut the link between them. The nodes do not use it.

:class:`TwoHosts` makes two Linux network namespaces, the rig computer's (``rig``) and the workstation's
(``station``), joined by a veth pair (``rig_if`` in the rig's, ``station_if`` in the station's) on
``<subnet>.0/24``: the rig at ``<subnet>.1``, the station at ``<subnet>.2``, loopback up in both, and in both
a route for multicast (224.0.0.0/4) over the veth, which DDS discovery needs (ROS_AUTOMATIC_DISCOVERY_RANGE
=SUBNET). A process runs on a host under ``ip netns exec <rig|station>``, or moves itself there
(:meth:`TwoHosts.enter_rig`). :meth:`TwoHosts.cut` takes the rig's end down, :meth:`TwoHosts.connect` brings
both ends back up; :meth:`TwoHosts.remove` deletes the namespaces (and with them the veth pair).

Each user passes its own subnet and a short name tag: the names are the tag and this process's id, so a
chaos run and a test at once never meet on a namespace or a link.

It needs root (CAP_SYS_ADMIN makes a namespace, CAP_NET_ADMIN the links) and iproute2's ``ip``.
:func:`problem` says why this machine cannot make the two hosts ('' if it can): a test skips with it, the
soak's chaos run says the cut SKIPPED with it. A step of :meth:`TwoHosts.create` that fails anyway raises
``subprocess.CalledProcessError`` (``OSError`` when ``ip`` cannot start); :meth:`TwoHosts.remove` deletes
the namespaces it made. Plain Python (ctypes); no ROS.
"""
from __future__ import annotations

import ctypes
import os
import shutil
import subprocess

CLONE_NEWNET = 0x40000000  # <sched.h>: setns() into a network namespace
IFNAMSIZ = 15  # the longest Linux interface name [characters]


def problem() -> str:
    """Why this machine cannot make two network namespaces and cut a link between them ('' if it can)."""
    if os.geteuid() != 0:
        return "not root (network namespaces need CAP_SYS_ADMIN)"
    if shutil.which("ip") is None:
        return "no iproute2 'ip' command"
    return ""


def ip(*args: str) -> None:
    """Runs iproute2's ``ip`` with ``args``; raises CalledProcessError if it fails."""
    subprocess.run(["ip", *args], check=True, capture_output=True, timeout=10)


class TwoHosts:
    """Namespaces ``rig`` and ``station`` with veth ends ``rig_if`` and ``station_if`` on ``subnet``.0/24."""

    def __init__(self, subnet: str, tag: str) -> None:
        """``subnet``: the network's first three octets ("10.77.0"); ``tag``: a letter or two that sets this
        user's names apart from another's (``<tag>rig<pid>``, ``<tag>sta<pid>``; links ``<tag>r<pid>``,
        ``<tag>s<pid>``)."""
        number = os.getpid() % 100000
        if not tag.isalnum() or len(f"{tag}r{number}") > IFNAMSIZ:
            raise ValueError(f"two hosts: tag {tag!r} must be letters or digits, at most {IFNAMSIZ - 6} of them")
        self.subnet = subnet
        self.rig, self.station = f"{tag}rig{number}", f"{tag}sta{number}"
        self.rig_if, self.station_if = f"{tag}r{number}", f"{tag}s{number}"

    def create(self) -> None:
        ip("netns", "add", self.rig)
        ip("netns", "add", self.station)
        ip("link", "add", self.rig_if, "type", "veth", "peer", "name", self.station_if)
        for ns, dev, host in ((self.rig, self.rig_if, 1), (self.station, self.station_if, 2)):
            ip("link", "set", dev, "netns", ns)
            ip("-n", ns, "addr", "add", f"{self.subnet}.{host}/24", "dev", dev)
            ip("-n", ns, "link", "set", "lo", "up")
        self.connect()

    def connect(self) -> None:
        """Both ends up, with the multicast route discovery needs (a link going down drops it)."""
        for ns, dev in ((self.rig, self.rig_if), (self.station, self.station_if)):
            ip("-n", ns, "link", "set", dev, "up")
            ip("-n", ns, "route", "replace", "224.0.0.0/4", "dev", dev)

    def cut(self) -> None:
        """The rig's end down: nothing crosses until :meth:`connect`."""
        ip("-n", self.rig, "link", "set", self.rig_if, "down")

    def enter_rig(self) -> None:
        """Move this process (its only thread: call it before rclpy starts any) into the rig's namespace, so
        that every process it starts runs there too."""
        fd = os.open(f"/var/run/netns/{self.rig}", os.O_RDONLY)
        try:
            if ctypes.CDLL(None, use_errno=True).setns(fd, CLONE_NEWNET) != 0:
                raise OSError(ctypes.get_errno(), f"setns into {self.rig}")
        finally:
            os.close(fd)

    def remove(self) -> None:
        """Deletes both namespaces, those that exist (a failed ``ip netns del`` is ignored)."""
        for ns in (self.rig, self.station):  # removing a namespace removes its end of the veth pair
            subprocess.run(["ip", "netns", "del", ns], capture_output=True, timeout=10)
