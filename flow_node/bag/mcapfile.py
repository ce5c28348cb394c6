"""MCAP at the record level: CRCs written into a finished file, checked on read, and the messages of a file
without its summary (a recorder that crashed) recovered by scanning.

rosbags 0.11's MCAP writer leaves every CRC field 0 ("not computed", which the format allows) and its reader
checks a chunk's CRC only when it is non-zero. :func:`add_crcs` fills them in place after rosbags closed the
file (chunk ``uncompressed_crc``, the data section CRC in DataEnd, the summary CRC in the Footer; no offset
moves). :func:`verify` checks the data section and summary CRCs, so a flipped byte anywhere in a bag we wrote
is an error instead of other numbers. :func:`scan` walks the records from the start, as far as they are intact
(an uncompressed chunk cut short still gives its complete messages). Format: https://mcap.dev/spec.
"""

from __future__ import annotations

import mmap
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from rosbags.rosbag2.storage_mcap import decompress

from ..core.errors import FileFormatError

MAGIC = b"\x89MCAP0\r\n"
SCHEMA, CHANNEL, MESSAGE, CHUNK, DATA_END, FOOTER = 0x03, 0x04, 0x05, 0x06, 0x0F, 0x02
_FOOTER_SIZE = 1 + 8 + 20  # opcode, length, summary_start, summary_offset_start, summary_crc


class McapDamage(FileFormatError):
    """An MCAP file whose bytes do not match its CRCs, or whose records cannot be parsed."""


def records(buf: bytes | mmap.mmap, start: int, end: int) -> Iterator[tuple[int, int, int]]:
    """(opcode, body start, body end) of the complete records in ``buf[start:end]``; stops at the first
    record that does not fit (a truncated file)."""
    pos = start
    while pos + 9 <= end:
        op, length = buf[pos], struct.unpack_from("<Q", buf, pos + 1)[0]
        body = pos + 9
        if body + length > end:
            return
        yield op, body, body + length
        pos = body + length


def _string(buf: bytes, pos: int) -> tuple[str, int]:
    n = struct.unpack_from("<I", buf, pos)[0]
    return bytes(buf[pos + 4:pos + 4 + n]).decode("utf-8"), pos + 4 + n


def _chunk_fields(buf: bytes | mmap.mmap, body: int) -> tuple[int, int, str, int, int]:
    """A chunk record's (uncompressed size, CRC, compression, records start, records length)."""
    size, crc = struct.unpack_from("<QI", buf, body + 16)
    compression, pos = _string(buf, body + 28)
    length = struct.unpack_from("<Q", buf, pos)[0]
    return size, crc, compression, pos + 8, length


def _footer(buf: bytes | mmap.mmap) -> tuple[int, int, int] | None:
    """(footer record offset, summary start, summary CRC) if the file ends with a footer and magic."""
    at = len(buf) - len(MAGIC) - _FOOTER_SIZE
    if at < len(MAGIC) or buf[-len(MAGIC):] != MAGIC or buf[at] != FOOTER:
        return None
    summary_start, _, crc = struct.unpack_from("<QQI", buf, at + 9)
    return at, summary_start, crc


def unfinished(path: str | Path) -> bool:
    """Whether the file starts as an MCAP but does not end as a complete one (no footer and closing magic):
    what a recorder that crashed leaves behind."""
    with open(path, "rb") as fh:
        head = fh.read(len(MAGIC))
        size = fh.seek(0, 2)
        fh.seek(max(0, size - len(MAGIC) - _FOOTER_SIZE))
        tail = fh.read()
    complete = len(tail) == len(MAGIC) + _FOOTER_SIZE and tail[0] == FOOTER and tail.endswith(MAGIC)
    return head == MAGIC and not complete


def _data_end(buf: bytes | mmap.mmap, end: int) -> int | None:
    """Offset of the DataEnd record (the data section ends there), walking the top-level records."""
    for op, body, _ in records(buf, len(MAGIC), end):
        if op == DATA_END:
            return body - 9
    return None


def add_crcs(path: str | Path) -> None:
    """Fill in the chunk, data section and summary CRCs of a complete MCAP file, in place."""
    with open(path, "r+b") as fh, mmap.mmap(fh.fileno(), 0) as buf:
        foot = _footer(buf)
        if foot is None:
            raise McapDamage(f"{path}: not a complete MCAP file (no footer)")
        at, summary_start, _ = foot
        data_end = None
        for op, body, _ in records(buf, len(MAGIC), at):
            if op == CHUNK:
                size, _, compression, start, length = _chunk_fields(buf, body)
                raw = decompress(bytes(buf[start:start + length]), compression, size, 0)
                struct.pack_into("<I", buf, body + 24, zlib.crc32(raw))
            elif op == DATA_END:
                data_end = body - 9
                break
        if data_end is not None:
            struct.pack_into("<I", buf, data_end + 9, zlib.crc32(buf[:data_end]))
        if summary_start:
            struct.pack_into("<I", buf, at + 25, zlib.crc32(buf[summary_start:at + 25]))
        buf.flush()


def verify(path: str | Path) -> None:
    """McapDamage unless the data section and summary match their CRCs (fields left 0 are not checked; a
    file without a footer is :func:`scan`'s business)."""
    if Path(path).stat().st_size < 2 * len(MAGIC) + _FOOTER_SIZE:
        return  # too short to be complete: rosbags (or scan) says what it is
    with open(path, "rb") as fh, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as buf:
        foot = _footer(buf)
        if foot is None:
            return
        at, summary_start, summary_crc = foot
        if summary_start and summary_crc and not len(MAGIC) <= summary_start <= at:
            raise McapDamage(f"{Path(path).name}: the footer points outside the file: corrupt")
        if summary_start and summary_crc and zlib.crc32(buf[summary_start:at + 25]) != summary_crc:
            raise McapDamage(f"{Path(path).name}: the summary section fails its CRC: corrupt")
        data_end = _data_end(buf, summary_start or at)
        if data_end is None:
            raise McapDamage(f"{Path(path).name}: no DataEnd record before the summary: corrupt")
        crc = struct.unpack_from("<I", buf, data_end + 9)[0]
        if crc and zlib.crc32(buf[:data_end]) != crc:
            raise McapDamage(f"{Path(path).name}: the data section (messages) fails its CRC: corrupt")


@dataclass
class Scan:
    """What a scan found: schemas (id -> (name, encoding, text)), channels (id -> (topic, schema id,
    message encoding)), messages (channel id, log time ns, data) in file order, and how far it got."""

    schemas: dict[int, tuple[str, str, str]] = field(default_factory=dict)
    channels: dict[int, tuple[str, int, str]] = field(default_factory=dict)
    messages: list[tuple[int, int, bytes]] = field(default_factory=list)
    file_bytes: int = 0
    intact_bytes: int = 0  # bytes from the start that parsed as complete records
    complete: bool = False  # a footer was reached
    stopped: str = ""  # why the scan ended early ("" if it reached the footer)


def _inner(scan: Scan, buf: bytes, start: int, end: int) -> int:
    """Parse the records inside a chunk (or the data section); returns where the last complete one ended."""
    pos = start
    for op, body, stop in records(buf, start, end):
        if op == SCHEMA:
            sid = struct.unpack_from("<H", buf, body)[0]
            name, p = _string(buf, body + 2)
            encoding, p = _string(buf, p)
            n = struct.unpack_from("<I", buf, p)[0]
            scan.schemas[sid] = (name, encoding, bytes(buf[p + 4:p + 4 + n]).decode("utf-8", "replace"))
        elif op == CHANNEL:
            cid, sid = struct.unpack_from("<HH", buf, body)
            topic, p = _string(buf, body + 4)
            encoding, p = _string(buf, p)
            scan.channels[cid] = (topic, sid, encoding)
        elif op == MESSAGE:
            cid, _, log_time = struct.unpack_from("<HIQ", buf, body)
            scan.messages.append((cid, log_time, bytes(buf[body + 22:stop])))
        pos = stop
    return pos


def scan(path: str | Path) -> Scan:
    """Read every intact record of an MCAP file from the start, without its summary. A chunk that is cut
    short is read as far as its records are complete if uncompressed (lost if compressed); a chunk whose CRC
    does not match ends the scan (what follows cannot be trusted)."""
    buf = Path(path).read_bytes()
    out = Scan(file_bytes=len(buf))
    if not buf.startswith(MAGIC):
        raise McapDamage(f"{Path(path).name}: not an MCAP file (bad magic)")
    pos = len(MAGIC)
    try:
        for op, body, stop in records(buf, pos, len(buf)):
            if op == CHUNK:
                size, crc, compression, start, length = _chunk_fields(buf, body)
                try:
                    raw = decompress(buf[start:start + length], compression, size, crc)
                except Exception as exc:  # noqa: BLE001 -- any failure here means the chunk is damaged
                    out.stopped = f"a chunk at byte {body - 9} is damaged ({exc})"
                    return out
                _inner(out, raw, 0, len(raw))
            elif op in (SCHEMA, CHANNEL, MESSAGE):
                _inner(out, buf, body - 9, stop)
            elif op in (DATA_END, FOOTER):
                out.intact_bytes, out.complete = stop, True
                return out
            pos = out.intact_bytes = stop
        # the record at ``pos`` is cut short: salvage an uncompressed chunk's complete records
        if pos + 9 + 28 <= len(buf) and buf[pos] == CHUNK:
            _, _, compression, start, _ = _chunk_fields(buf, pos + 9)
            if compression == "" and start <= len(buf):
                out.intact_bytes = _inner(out, buf, start, len(buf))
        out.stopped = f"the file ends inside the record at byte {pos}"
    except (struct.error, UnicodeDecodeError, IndexError) as exc:
        out.stopped = f"unparsable record after byte {out.intact_bytes} ({type(exc).__name__})"
    return out
