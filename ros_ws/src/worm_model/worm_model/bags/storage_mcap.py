"""The reader's MCAP storage plugin: one rosbag2 ``.mcap`` file (profile ``ros2``), any rosbag2 version.

Reads the summary when the file has one and scans the file when it has not
(a recorder killed before closing it); tells a file merely missing its footer
(nothing lost) from one cut inside a record (messages lost: ``damage``).
Yields its topics, the schemas as embedded definitions, the metadata Jazzy on
embeds, and its messages in log-time order (integer ns).

Raises:
    :class:`~worm_model.errors.BagReadError` naming the file.
"""

from __future__ import annotations

import struct
from collections.abc import Collection, Iterator
from pathlib import Path

from mcap.exceptions import McapError
from mcap.reader import NonSeekingReader, SeekingReader
from mcap.records import Channel, DataEnd, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

from worm_model.errors import BagReadError
from worm_model.bags.metadata import BagMetadata, parse_embedded_metadata
from worm_model.bags.storage import MessageDefinition, StorageTopic

__all__ = ['McapFile']

#: the magic (8 bytes) and the smallest header record (opcode, length, two empty strings: 17 bytes)
_HEAD_BYTES = 8 + 17


class McapFile:
    """A rosbag2 MCAP storage file (profile ``ros2``), any rosbag2 version.

    Channel metadata ``offered_qos_profiles`` (all versions) and
    ``topic_type_hash`` (Iron+); schemas ``ros2msg``/``ros2idl`` with the
    full definition text; a metadata record ``rosbag2`` holding
    ``ROS_DISTRO`` (Humble to 0.24) or ``serialized_metadata`` (Jazzy+).
    A file without a summary section (recorder killed) is read by scanning.
    """

    def __init__(self, path: Path, name: str) -> None:
        """Open ``path`` and read its schemas, channels and metadata.

        Raises:
            BagReadError: Not an MCAP file or unreadable.

        """
        self.name = name
        self.path = path
        self.warnings: list[str] = []
        try:
            self.stream = path.open('rb')
        except OSError as err:
            msg = f'Cannot open MCAP storage file {path}: {err}'
            raise BagReadError(msg) from err
        self.seekable = False
        self.embedded_metadata: BagMetadata | None = None
        #: why the file is damaged (data lost), "" if it is not
        self.damage = ''
        try:
            self._read_summary()
        except (McapError, OSError, ValueError, EOFError, struct.error) as err:
            self.stream.close()
            size = path.stat().st_size if path.exists() else 0
            if size < _HEAD_BYTES:  # the file a recorder opened and has not flushed into yet
                msg = (f'Cannot read MCAP storage file {path}: it holds {size} bytes, less than an MCAP '
                       "file's magic and header: a recorder that has not flushed yet leaves it so")
            else:
                msg = f'Cannot read MCAP storage file {path}: {err!r}'
            raise BagReadError(msg) from err

    def _read_summary(self) -> None:
        reader = SeekingReader(self.stream)
        try:
            summary = reader.get_summary()
        except (McapError, EOFError, ValueError, struct.error, OSError):
            # OSError: a file shorter than a footer, whose seek to it goes before the start
            summary = None
        if summary is not None:
            self.seekable = True
            schemas, channels = summary.schemas, summary.channels
            records = [m for m in reader.iter_metadata() if m.name == 'rosbag2']
        else:
            self.warnings.append(f'{self.path}: no MCAP summary (file not closed); scanned instead')
            schemas, channels, records = {}, {}, []
            self.stream.seek(0)
            messages = 0
            size = self.path.stat().st_size
            end = 0  # where the last complete record ends
            try:
                for record in StreamReader(self.stream, record_size_limit=None).records:
                    end = self.stream.tell()
                    if isinstance(record, Schema):
                        schemas[record.id] = record
                    elif isinstance(record, Channel):
                        channels[record.id] = record
                    elif isinstance(record, Message):
                        messages += 1
                    elif isinstance(record, Metadata) and record.name == 'rosbag2':
                        records.append(record)
                    elif isinstance(record, DataEnd):
                        break  # every message is before it: a cut in the summary loses none
            except (McapError, EOFError, ValueError, struct.error) as err:
                if end == size:  # it ends after a complete record: a writer stopped (killed) between two
                    self.warnings.append(f'{self.path}: ends after {messages} message(s) without its '
                                         'footer: the writer stopped before closing it')
                else:
                    self.damage = (f'{self.path}: truncated: it ends inside a record ({type(err).__name__}) '
                                   f'of its {size} bytes, so the messages of the cut-off part are lost; '
                                   f'{messages} message(s) before the cut can be read')
        self.topics = []
        self._channel_topics: dict[int, str] = {}
        seen: set[str] = set()
        for channel in channels.values():
            schema = schemas.get(channel.schema_id)
            self._channel_topics[channel.id] = channel.topic
            if channel.topic in seen:
                continue
            seen.add(channel.topic)
            self.topics.append(StorageTopic(
                name=channel.topic,
                type=schema.name if schema else '',
                serialization_format=channel.message_encoding,
                offered_qos_profiles=channel.metadata.get('offered_qos_profiles', ''),
                type_hash=channel.metadata.get('topic_type_hash', ''),
                definition=_schema_definition(schema),
            ))
        for record in reversed(records):
            if text := record.metadata.get('serialized_metadata'):
                self.embedded_metadata = parse_embedded_metadata(
                    text, f'{self.path}: metadata record rosbag2')
                break
        if self.embedded_metadata is None and records:
            distro = records[-1].metadata.get('ROS_DISTRO', '')
            self.embedded_metadata = None if not distro else BagMetadata(
                ros_distro=distro, storage_identifier='mcap', source=str(self.path))

    def messages(self, topics: Collection[str] | None) -> Iterator[tuple[str, int, bytes]]:
        """Yield ``(topic, log_time_ns, data)`` in log-time order.

        Raises:
            BagReadError: The file is damaged (a truncated file without
                summary ends quietly where it ends instead).

        """
        self.stream.seek(0)
        try:
            if self.seekable:
                wanted = None if topics is None else list(topics)
                for _schema, channel, message in SeekingReader(self.stream).iter_messages(
                        topics=wanted, log_time_order=True):
                    yield channel.topic, message.log_time, message.data
                return
            found = []
            try:
                for _schema, channel, message in NonSeekingReader(
                        self.stream, record_size_limit=None).iter_messages(log_time_order=False):
                    if topics is None or channel.topic in topics:
                        found.append((message.log_time, message.sequence, channel.topic, message.data))
            except (McapError, EOFError, struct.error):
                pass  # truncated
            found.sort(key=lambda m: m[:2])
            for log_time, _sequence, topic, data in found:
                yield topic, log_time, data
        except (McapError, OSError, ValueError, struct.error) as err:
            msg = f'Cannot read messages of MCAP storage file {self.path}: {err!r}'
            raise BagReadError(msg) from err

    def close(self) -> None:
        """Close the file."""
        self.stream.close()


def _schema_definition(schema: Schema | None) -> MessageDefinition | None:
    if schema is None:
        return None
    try:
        text = schema.data.decode('utf-8')
    except UnicodeDecodeError:
        return None
    return MessageDefinition(schema.encoding, text)
