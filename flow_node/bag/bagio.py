"""rosbag2 reading and writing on the ``rosbags`` library: clean one-line errors, typed messages.

Every failure a user can cause (missing path, not a bag, truncated or corrupt storage, missing topic) is
raised as :class:`BagError`, a :class:`~flow_node.core.errors.FileFormatError`. MCAP bags are written with
CRCs and checked against them on open (:mod:`flow_node.bag.mcapfile`); an MCAP without its summary (a
recorder that crashed) is read as far as it is intact by :class:`RecoveredReader`, which says how much.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path
from typing import Any

from rosbags.interfaces import Connection, ConnectionExtRosbag2, MessageDefinition, MessageDefinitionFormat
from rosbags.rosbag2 import Reader, Writer
from rosbags.rosbag2.enums import StoragePlugin
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from ..core.errors import FileFormatError, one_line
from . import mcapfile

IMAGE = "sensor_msgs/msg/Image"
COMPRESSED = "sensor_msgs/msg/CompressedImage"
IMAGE_TYPES = (IMAGE, COMPRESSED)
STORAGES = ("mcap", "sqlite3")
NS = 1_000_000_000


class BagError(FileFormatError):
    """A bag that cannot be read or written as asked: missing, corrupt, truncated, wrong topic or size."""


@lru_cache(maxsize=1)
def typestore() -> Typestore:
    """The ROS 2 Jazzy message types (rosbags' built-in store)."""
    return get_typestore(Stores.ROS2_JAZZY)


def _reason(exc: BaseException) -> str:
    """A one-line reason for a low-level exception."""
    return one_line(exc, 200) or type(exc).__name__


# Storage plugins raise a variety of exceptions on damaged files (struct, sqlite3, KeyError, rosbags'
# ReaderError...); at this boundary every one of them means the same thing to the user.
_READ_ERRORS = (Exception,)


class RecoveredReader:
    """The readable part of MCAP storage files that have no summary, with the part of rosbags' Reader
    interface flow_bag uses (``path``, ``connections``, ``messages``, ``close``). Messages come in log-time
    order. ``recovery`` says, in one line, what was found and how much was lost."""

    def __init__(self, path: Path, files: Sequence[Path]) -> None:
        self.path = path
        scans = [(f, mcapfile.scan(f)) for f in files]
        ids: dict[tuple[str, str], int] = {}
        defs: dict[tuple[str, str], str] = {}
        self._messages: list[tuple[int, int, bytes]] = []
        for _, sc in scans:
            local = {}
            for cid, (topic, sid, _) in sc.channels.items():
                name, _, text = sc.schemas.get(sid, ("", "", ""))
                key = (topic, name)
                local[cid] = ids.setdefault(key, len(ids) + 1)
                defs.setdefault(key, text)
            self._messages += [(local[c], t, d) for c, t, d in sc.messages if c in local]
        self._messages.sort(key=lambda m: m[1])
        counts = {i: 0 for i in ids.values()}
        for cid, _, _ in self._messages:
            counts[cid] += 1
        self.connections = [Connection(i, k[0], k[1], MessageDefinition(MessageDefinitionFormat.MSG, defs[k]), "",
                                       counts[i], ConnectionExtRosbag2("cdr", []), self) for k, i in ids.items()]
        per_topic = ", ".join(f"{c.topic} {c.msgcount}" for c in self.connections)
        damaged = [(f, sc) for f, sc in scans if not sc.complete]
        what = ("; ".join(f"{f.name} has no summary ({sc.stopped}; {sc.intact_bytes} of {sc.file_bytes} bytes "
                          "intact)" for f, sc in damaged) if damaged else "no usable metadata.yaml")
        self.recovery = (f"{path}: {what}: the recorder did not finish it; recovered {len(self._messages)} "
                         f"messages by scanning ({per_topic or 'none'})")
        self.recovered = {"messages": len(self._messages), "per_topic": {c.topic: c.msgcount for c in self.connections},
                          "files": {f.name: {"bytes": sc.file_bytes, "intact_bytes": sc.intact_bytes,
                                             "complete": sc.complete, "stopped": sc.stopped} for f, sc in scans}}

    def messages(self, connections: Sequence[Connection] = ()) -> Iterator[tuple[Connection, int, bytes]]:
        by_id = {c.id: c for c in self.connections}
        wanted = {c.id for c in connections} or set(by_id)
        return ((by_id[c], t, d) for c, t, d in self._messages if c in wanted)

    def close(self) -> None:
        """Nothing to release (the scan read the files)."""


def _storage_files(folder: Path) -> list[Path]:
    """The MCAP storage files of a bag folder, in name order."""
    return sorted(folder.glob("*.mcap")) if folder.is_dir() else []


def _check_crcs(files: Sequence[Path], path: str | Path) -> None:
    """BagError if a complete MCAP file does not match its CRCs."""
    for f in files:
        try:
            mcapfile.verify(f)
        except (OSError, ValueError) as exc:
            raise BagError(f"{path}: {_reason(exc)}") from None


@contextmanager
def open_bag(path: str | Path) -> Iterator[Reader | RecoveredReader]:
    """Open a rosbag2 folder (or a single .mcap/.db3 file's folder) for reading; BagError if impossible.

    MCAP files are checked against their CRCs first. When rosbags cannot open the bag and its MCAP files
    lack their summary (or metadata.yaml is missing), a :class:`RecoveredReader` is returned instead.
    """
    p = Path(path)
    if not p.exists():
        raise BagError(f"{path}: no such bag")
    if p.is_file() and p.suffix in (".mcap", ".db3"):
        p = p.parent
    files = _storage_files(p)
    _check_crcs(files, path)
    try:
        reader: Reader | RecoveredReader = Reader(p)
        reader.open()
    except _READ_ERRORS as exc:
        unfinished = [f for f in files if mcapfile.unfinished(f)]
        if not unfinished and (not files or (p / "metadata.yaml").exists()):
            raise BagError(f"{path}: cannot open bag: {_reason(exc)}") from exc
        try:
            reader = RecoveredReader(p, files)
        except (OSError, ValueError) as damage:
            raise BagError(f"{path}: cannot open bag: {_reason(exc)}; scanning failed: {_reason(damage)}") from None
        if not reader.recovered["messages"]:
            raise BagError(f"{path}: cannot open bag: {_reason(exc)}; scanning its MCAP found no message") from None
    try:
        yield reader
    finally:
        try:
            reader.close()
        except _READ_ERRORS:
            pass


def find_connections(reader: Reader, topic: str | None, msgtypes: Sequence[str], what: str,
                     required: bool = True, exclude: Sequence[str] = ()) -> list[Connection]:
    """Connections of ``topic`` (or, if None, of the single topic not in ``exclude`` whose type is in
    ``msgtypes``). Raises BagError when the topic is missing, of the wrong type, or ambiguous (and
    ``required``).
    """
    conns = [c for c in reader.connections if c.msgtype in msgtypes and c.topic not in exclude]
    if topic is not None:
        named = [c for c in reader.connections if c.topic == topic]
        if not named:
            if not required:
                return []
            have = ", ".join(sorted({c.topic for c in reader.connections})) or "none"
            raise BagError(f"{what} topic {topic} is not in the bag (topics: {have})")
        bad = [c.msgtype for c in named if c.msgtype not in msgtypes]
        if bad:
            raise BagError(f"{what} topic {topic} has type {bad[0]}, expected {' or '.join(msgtypes)}")
        return named
    topics = sorted({c.topic for c in conns})
    if len(topics) == 1:
        return [c for c in conns if c.topic == topics[0]]
    if not required:
        return []
    if not topics:
        raise BagError(f"no {what} topic of type {' or '.join(msgtypes)} in the bag")
    raise BagError(f"several {what} topics ({', '.join(topics)}); choose one with --{what}-topic")


def read_messages(reader: Reader, connections: Sequence[Connection]) -> Iterator[tuple[Connection, int, bytes]]:
    """Raw messages (connection, bag time ns, CDR bytes) in time order; BagError on damaged storage."""
    if not connections:
        return
    it = reader.messages(connections=connections)
    while True:
        try:
            item = next(it)
        except StopIteration:
            return
        except _READ_ERRORS as exc:
            raise BagError(f"{reader.path}: bag is corrupt or truncated: {_reason(exc)}") from exc
        yield item


def deserialize(raw: bytes, msgtype: str) -> Any:
    """CDR bytes -> rosbags message object; BagError if the bytes do not decode."""
    try:
        return typestore().deserialize_cdr(raw, msgtype)
    except _READ_ERRORS as exc:
        raise BagError(f"a {msgtype} message does not decode: {_reason(exc)}") from exc


def header(stamp_ns: int, frame_id: str) -> Any:
    """std_msgs/Header with the given stamp (ns) and frame."""
    ts = typestore()
    stamp = ts.types["builtin_interfaces/msg/Time"](sec=stamp_ns // NS, nanosec=stamp_ns % NS)
    return ts.types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)


def stamp_ns(msg: Any) -> int:
    """Header stamp of a message in ns."""
    return int(msg.header.stamp.sec) * NS + int(msg.header.stamp.nanosec)


def image_message(hdr: Any, fields: dict[str, Any]) -> Any:
    """sensor_msgs/Image from a header and the fields height, width, encoding, is_bigendian, step, data."""
    return typestore().types[IMAGE](header=hdr, **fields)


def compressed_message(hdr: Any, fmt: str, data: Any) -> Any:
    """sensor_msgs/CompressedImage from a header, a format string ('png', 'jpeg') and encoded bytes."""
    return typestore().types[COMPRESSED](header=hdr, format=fmt, data=data)


class BagWriter:
    """A rosbag2 being written: connections by topic, messages serialised with the Jazzy types.

    Use as a context manager; on an exception the partial bag is left for the caller to delete. MCAP files
    get their CRCs when the writer closes.
    """

    def __init__(self, path: str | Path, storage: str = "mcap") -> None:
        self._path, self._storage = Path(path), storage
        if storage not in STORAGES:
            raise BagError(f"unknown storage {storage!r}; choose mcap or sqlite3")
        plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        try:
            self._writer = Writer(Path(path), version=Writer.VERSION_LATEST, storage_plugin=plugin)
        except _READ_ERRORS as exc:
            raise BagError(f"cannot create bag {path}: {_reason(exc)}") from exc
        self._conns: dict[str, Connection] = {}

    def __enter__(self) -> BagWriter:
        self._writer.open()
        return self

    def __exit__(self, exc_type: object, *exc: object) -> None:
        self._writer.close()
        if exc_type is None and self._storage == "mcap":
            for f in _storage_files(self._path):
                mcapfile.add_crcs(f)  # rosbags writes none: see flow_node.bag.mcapfile

    def add_topic(self, topic: str, msgtype: str, like: Connection | None = None) -> None:
        """Register ``topic``; ``like`` copies the definition of an input connection (raw passthrough)."""
        if like is not None and like.msgdef.data and like.digest:
            self._conns[topic] = self._writer.add_connection(topic, msgtype, msgdef=like.msgdef.data,
                                                             rihs01=like.digest)
        else:
            self._conns[topic] = self._writer.add_connection(topic, msgtype, typestore=typestore())

    def write(self, topic: str, time_ns: int, msg: Any) -> None:
        """Serialise ``msg`` and write it on ``topic`` (registered) at bag time ``time_ns``."""
        conn = self._conns[topic]
        self._writer.write(conn, time_ns, typestore().serialize_cdr(msg, conn.msgtype))

    def write_raw(self, topic: str, time_ns: int, raw: bytes) -> None:
        """Write already serialised CDR bytes on ``topic``."""
        self._writer.write(self._conns[topic], time_ns, raw)
