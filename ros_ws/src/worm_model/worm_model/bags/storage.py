"""What a storage plugin of the reader yields: the interface each one implements, and the topics it declares.

One plugin per storage rosbag2 writes (:mod:`worm_model.bags.storage_sqlite3`,
:mod:`worm_model.bags.storage_mcap`); :mod:`worm_model.bags.bag_files` picks
the one that reads a file, :class:`~worm_model.bags.reader.BagReader` merges
what they yield. Timestamps are receive times, integer ns.
"""

from __future__ import annotations

from collections.abc import Collection, Iterator
from dataclasses import dataclass
from typing import Protocol

from worm_model.bags.metadata import BagMetadata

__all__ = [
    'MessageDefinition',
    'StorageFile',
    'StorageTopic',
]


@dataclass(frozen=True, slots=True)
class MessageDefinition:
    """A type's definition as embedded in a bag."""

    encoding: str
    """``ros2msg`` or ``ros2idl`` (empty or ``unknown``: none)."""
    text: str
    """The definition with its dependencies, rosbag2's concatenated format."""

    @property
    def usable(self) -> bool:
        """Whether there is a definition to parse."""
        return self.encoding in ('ros2msg', 'ros2idl') and bool(self.text.strip())


@dataclass(frozen=True, slots=True)
class StorageTopic:
    """A topic as one storage file declares it."""

    name: str
    type: str
    serialization_format: str
    offered_qos_profiles: str
    """As stored: YAML text (may be empty)."""
    type_hash: str
    definition: MessageDefinition | None


class StorageFile(Protocol):
    """One open storage file of a bag."""

    name: str
    """Its name in the bag (the compressed name for a decompressed file)."""
    topics: list[StorageTopic]
    embedded_metadata: BagMetadata | None
    """The last metadata rosbag2 wrote into the file (Humble+ sqlite3, Jazzy+ MCAP)."""

    def messages(self, topics: Collection[str] | None) -> Iterator[tuple[str, int, bytes]]:
        """Yield ``(topic, timestamp_ns, data)`` in timestamp order."""
        ...

    def close(self) -> None:
        """Release the file."""
        ...
