"""The reader's sqlite3 storage plugin: one rosbag2 ``.db3`` file, any schema version (1 to 4).

Opened read-only (immutable unless a crashed recorder left a ``-wal`` file
holding data); yields its topics, the definitions Iron on embeds, the
metadata Humble on embeds, and its messages in timestamp order (integer ns).

Raises:
    :class:`~worm_model.errors.BagReadError` naming the file.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Collection, Iterator
from pathlib import Path
from urllib.parse import quote

from worm_model.errors import BagReadError
from worm_model.bags.metadata import BagMetadata, parse_embedded_metadata
from worm_model.bags.storage import MessageDefinition, StorageTopic

__all__ = ['Sqlite3File']


class Sqlite3File:
    """A rosbag2 sqlite3 storage file, any schema version (1 to 4).

    Schema history (``rosbag2_storage_sqlite3`` / ``_default_plugins``):
    Foxy/Galactic: ``topics(id, name, type, serialization_format,
    offered_qos_profiles)`` and ``messages(id, topic_id, timestamp, data)``;
    Humble adds the ``schema(schema_version, ros_distro)`` and
    ``metadata(id, metadata_version, metadata)`` tables (schema 3); Iron adds
    ``topics.type_description_hash`` and the ``message_definitions`` table
    (schema 4). Eloquent and older lack ``offered_qos_profiles``.
    """

    def __init__(self, path: Path, name: str) -> None:
        """Open ``path`` read-only.

        Raises:
            BagReadError: Not an sqlite3 database, or not a rosbag2 one.

        """
        self.name = name
        self.path = path
        # A database left in WAL mode (Foxy writes them so) would make SQLite create
        # -wal/-shm files next to it; unless a -wal file holds data (a recorder that
        # crashed), open it immutable: nothing written, works on read-only media too.
        wal = path.with_name(path.name + '-wal')
        options = 'mode=ro' if wal.exists() and wal.stat().st_size else 'mode=ro&immutable=1'
        try:
            self.db = sqlite3.connect(f'file:{quote(str(path))}?{options}', uri=True)
            tables = {row[0] for row in self.db.execute(
                "SELECT name FROM sqlite_master WHERE type = 'table'")}
        except sqlite3.Error as err:
            msg = f'Cannot open sqlite3 storage file {path}: {err}'
            raise BagReadError(msg) from err
        missing = {'topics', 'messages'} - tables
        if missing:
            self.db.close()
            msg = f'{path} is not a rosbag2 sqlite3 file: no table {sorted(missing)[0]!r}'
            raise BagReadError(msg)
        try:
            self.topics, self._ids = self._read_topics(tables)
            self.embedded_metadata = self._read_metadata(tables)
        except sqlite3.Error as err:
            self.db.close()
            msg = f'Cannot read the topics of sqlite3 storage file {path}: {err}'
            raise BagReadError(msg) from err

    def _read_topics(self, tables: set[str]) -> tuple[list[StorageTopic], dict[int, str]]:
        columns = {row[1] for row in self.db.execute('PRAGMA table_info(topics)')}
        wanted = ['id', 'name', 'type', 'serialization_format']
        optional = ['offered_qos_profiles', 'type_description_hash']
        select = wanted + [c for c in optional if c in columns]
        definitions: dict[str, MessageDefinition] = {}
        if 'message_definitions' in tables:
            for type_name, encoding, text in self.db.execute(
                'SELECT topic_type, encoding, encoded_message_definition FROM message_definitions'
            ):
                definitions[type_name] = MessageDefinition(encoding or '', text or '')
        topics: list[StorageTopic] = []
        ids: dict[int, str] = {}
        for row in self.db.execute(f'SELECT {", ".join(select)} FROM topics ORDER BY id'):
            values = dict(zip(select, row, strict=True))
            ids[values['id']] = values['name']
            topics.append(StorageTopic(
                name=values['name'],
                type=values['type'],
                serialization_format=values['serialization_format'],
                offered_qos_profiles=values.get('offered_qos_profiles') or '',
                type_hash=values.get('type_description_hash') or '',
                definition=definitions.get(values['type']),
            ))
        return topics, ids

    def _read_metadata(self, tables: set[str]) -> BagMetadata | None:
        if 'metadata' not in tables:
            return None
        row = self.db.execute('SELECT metadata FROM metadata ORDER BY id DESC LIMIT 1').fetchone()
        return parse_embedded_metadata(row[0], f'{self.path}: table metadata') if row else None

    def messages(self, topics: Collection[str] | None) -> Iterator[tuple[str, int, bytes]]:
        """Yield ``(topic, timestamp_ns, data)`` ordered by timestamp, then insertion.

        Raises:
            BagReadError: The database is damaged.

        """
        query = 'SELECT topic_id, timestamp, data FROM messages'
        args: list[int] = []
        if topics is not None:
            ids = [i for i, name in self._ids.items() if name in topics]
            query += f' WHERE topic_id IN ({", ".join("?" * len(ids))})'
            args = ids
        query += ' ORDER BY timestamp, id'
        try:
            for topic_id, timestamp, data in self.db.execute(query, args):
                name = self._ids.get(topic_id)
                if name is None:
                    msg = f'{self.path}: a message refers to topic id {topic_id}, not in table topics'
                    raise BagReadError(msg)
                yield name, timestamp, data
        except sqlite3.Error as err:
            msg = f'Cannot read messages of sqlite3 storage file {self.path}: {err}'
            raise BagReadError(msg) from err

    def close(self) -> None:
        """Close the database."""
        self.db.close()
