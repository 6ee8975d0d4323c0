"""Recover a bag whose recorder did not finish it (killed, power cut): ``scripts/reindex.py``.

rosbag2's ``ros2 bag reindex`` rebuilds ``metadata.yaml``; an MCAP file cut short also lacks
its summary section (schemas, channels, chunk indexes, statistics) and footer, so neither
``rosbags`` nor the ``mcap`` reader opens it. :func:`reindex_bag` reads such a file record by
record from its start (``mcap.stream_reader.StreamReader``: no summary needed), keeps every
*complete* chunk and stops at the first record that is cut short or corrupt (a chunk with a
bad CRC is dropped, with everything after it), and writes a new MCAP with the same schemas,
channels, metadata records and messages (same bytes, same times, file order) through
:class:`~evoscen_record.recorder.BagRecorder` — so the result is what the recorder would have
written had it been closed after the last complete chunk — plus ``metadata.yaml``.

The damaged file is kept beside the new one as ``<file>.orig`` (no reader looks at it;
delete it once the reindexed bag is checked). A complete bag reindexes to a byte-identical
file.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from evoscen_contract import topics as T
from evoscen_contract.contract import EXIT_OK
from evoscen_sim.errors import InputError

from .recorder import DEFAULT_CHUNK_SIZE, BagRecorder

WORLD_TOPIC = T.WORLD.name


@dataclass
class ReindexResult:
    """What :func:`reindex_bag` recovered."""

    mcap_path: Path
    messages: int = 0
    topic_counts: dict[str, int] = field(default_factory=dict)
    steps: int = 0
    """Distinct stamps of ``/evoscen/world`` (the states t_0 .. t_K: K + 1 for a run of K steps)."""
    last_step_ns: int | None = None
    chunks: int = 0
    stopped: str = ""
    """Why reading stopped before the file's footer ('' = the file was complete)."""
    original: Path | None = None


def _mcap_of(bag: Path) -> Path:
    if bag.is_file():
        return bag
    if not bag.is_dir():
        raise InputError(f"bag {str(bag)!r}: no such bag directory or .mcap file")
    mcaps = sorted(bag.glob("*.mcap"))
    if len(mcaps) != 1:
        raise InputError(f"bag {str(bag)!r}: {len(mcaps)} .mcap files (expected exactly one)")
    return mcaps[0]


@dataclass
class _Contents:
    """What the readable part of a bag file holds (:func:`_read`)."""

    schemas: dict = field(default_factory=dict)
    channels: dict = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    messages: list = field(default_factory=list)
    chunks: int = 0
    stopped: str = ""

    def world_stamps(self) -> set[int]:
        """The log times of the world states (messages of channels without a record left out)."""
        world = {cid for cid, ch in self.channels.items() if ch.topic == WORLD_TOPIC}
        return {m.log_time for m in self.messages if m.channel_id in world}


def _read(path: Path) -> _Contents:
    """Read ``path`` record by record up to its first record cut short or corrupt (module docstring).

    Raises:
        InputError: the file cannot be opened, is not MCAP at all (bad magic), or holds no
            channel record (nothing to rebuild from); the message names the file.
    """
    from mcap.exceptions import McapError
    from mcap.records import Channel, Chunk, Message, Metadata, Schema
    from mcap.stream_reader import StreamReader, breakup_chunk

    out = _Contents()
    header_seen = False
    try:
        stream = open(path, "rb")  # noqa: SIM115
    except OSError as exc:
        raise InputError(f"bag {str(path)!r}: cannot open: {exc.strerror or exc}") from None
    with stream:
        records = StreamReader(stream, emit_chunks=True, validate_crcs=True).records
        while True:
            try:
                record = next(records)
            except StopIteration:
                break
            except (McapError, EOFError, ValueError, KeyError, IndexError, OSError) as exc:
                if not header_seen:
                    raise InputError(f"bag {str(path)!r}: not an MCAP file ({exc})") from None
                out.stopped = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
                break
            except Exception as exc:  # noqa: BLE001 - any decoder failure ends the readable part
                if not header_seen:
                    raise InputError(f"bag {str(path)!r}: not an MCAP file ({exc!r})") from None
                out.stopped = repr(exc)
                break
            header_seen = True
            inner = [record]
            if isinstance(record, Chunk):
                try:
                    inner = list(breakup_chunk(record, validate_crc=True))
                except Exception as exc:  # noqa: BLE001 - a corrupt chunk: stop before it
                    out.stopped = f"corrupt chunk: {exc!r}"
                    break
                out.chunks += 1
            for rec in inner:
                if isinstance(rec, Schema):
                    out.schemas.setdefault(rec.id, rec)
                elif isinstance(rec, Channel):
                    out.channels.setdefault(rec.id, rec)
                elif isinstance(rec, Message):
                    out.messages.append(rec)
                elif isinstance(rec, Metadata) and rec.name != "rosbag2":
                    out.metadata.setdefault(rec.name, dict(rec.metadata))
    if not out.channels:
        raise InputError(f"bag {str(path)!r}: no channel records readable; nothing to recover")
    return out


def _topics(path: Path, contents: _Contents) -> list:
    """The contract topic of each channel, in channel-id order; InputError for a foreign one."""
    topics = []
    for cid in sorted(contents.channels):
        ch = contents.channels[cid]
        spec = T.spec_of(ch.topic)  # the BV nodes' command topics too (docs/architecture.md §5, "BV nodes")
        if spec is None:
            raise InputError(f"bag {str(path)!r}: channel {ch.topic!r} is not an evoscen contract topic; "
                             "only evoscen bags can be reindexed")
        schema = contents.schemas.get(ch.schema_id)
        if schema is not None and schema.name != spec.type_name:
            raise InputError(f"bag {str(path)!r}: channel {ch.topic!r} has type {schema.name!r}, "
                             f"the contract says {spec.type_name!r}")
        topics.append(spec)
    return topics


def _rewrite(path: Path, contents: _Contents, result: ReindexResult, *, keep_original: bool) -> None:
    """Write the new bag beside ``path`` and put it in its place (module docstring)."""
    bag_dir = path.parent
    topics = _topics(path, contents)
    topic_of = {cid: ch.topic for cid, ch in contents.channels.items()}
    tmp = Path(tempfile.mkdtemp(prefix=".reindex-", dir=bag_dir))
    try:
        rec = BagRecorder(tmp / "bag", topics, compression=_compression_of(path), chunk_size=DEFAULT_CHUNK_SIZE,
                          canonicalize=False, metadata=contents.metadata, file_name=path.name)
        for m in contents.messages:
            topic = topic_of.get(m.channel_id)
            if topic is None:
                continue  # a message of a channel whose record was lost: cannot be typed
            rec.write(topic, m.data, m.log_time, m.publish_time, canonical=True)
        rec.close()
        result.topic_counts = rec.topic_message_counts()
        result.messages = rec.message_count
        if keep_original:
            result.original = path.with_name(path.name + ".orig")
            os.replace(path, result.original)
        os.replace(tmp / "bag" / path.name, path)
        os.replace(tmp / "bag" / "metadata.yaml", bag_dir / "metadata.yaml")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _result(path: Path, contents: _Contents) -> ReindexResult:
    stamps = contents.world_stamps()
    return ReindexResult(mcap_path=path, steps=len(stamps), last_step_ns=max(stamps) if stamps else None,
                         chunks=contents.chunks, stopped=contents.stopped)


def reindex_bag(bag: Path | str, *, keep_original: bool = True) -> ReindexResult:
    """Rebuild the MCAP summary and ``metadata.yaml`` of ``bag`` (a bag directory or its .mcap).

    Raises:
        InputError: no bag there, the file is not MCAP at all (bad magic), or it holds no
            schema/channel records (nothing to rebuild from); the message names the file.
    """
    path = _mcap_of(Path(bag))
    contents = _read(path)
    result = _result(path, contents)
    _rewrite(path, contents, result, keep_original=keep_original)
    return result


def recovered_lines(r: ReindexResult) -> list[str]:
    """What a reindex recovered, as ``scripts/reindex.py`` prints it: messages, world states, chunks and
    where reading stopped; the messages per topic; the bag (and the damaged file kept)."""
    last = "-" if r.last_step_ns is None else f"{r.last_step_ns / 1e9:.1f} s"
    return ([f"recovered {r.messages} messages, {r.steps} world states (last at {last}) from {r.chunks} chunks "
             + ("(the file was complete)" if not r.stopped else f"(read stopped at: {r.stopped})")]
            + [f"  {topic}: {n}" for topic, n in r.topic_counts.items()]
            + [f"bag: {r.mcap_path.parent}" + (f"  (damaged file kept as {r.original.name})" if r.original else "")])


def reindex_and_report(bag: Path, *, keep_original: bool = True) -> int:
    """``scripts/reindex.py``: :func:`reindex_bag`, then print :func:`recovered_lines`; returns :data:`EXIT_OK`. A file
    that cannot be read or written is a one-line InputError naming the bag too."""
    try:
        r = reindex_bag(bag, keep_original=keep_original)
    except OSError as exc:
        raise InputError(f"bag {str(bag)!r}: {exc.strerror or exc}") from None
    print("\n".join(recovered_lines(r)))
    return EXIT_OK


def _compression_of(path: Path) -> str:
    """The compression of the file's first chunk (what the recorder was told), zstd if none."""
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader

    try:
        with open(path, "rb") as f:
            for record in StreamReader(f, emit_chunks=True).records:
                if isinstance(record, Chunk):
                    return {"zstd": "zstd", "lz4": "lz4", "": "none"}.get(record.compression, "zstd")
    except Exception:  # noqa: BLE001 - a damaged file: the default
        pass
    return "zstd"


def finish_bag(bag_dir: Path) -> tuple[int, bool]:
    """Finish a bag cut back to its complete chunks after a fault of the host, in place (what
    :class:`~evoscen_record.recorder.BagRecorder` calls as its ``finish_after_fault``).

    Returns (the world states the file holds, whether the bag was finished). The count is read
    from the file, not taken from the writer: where the file could not be cut back (a file system
    made read-only), a chunk that reached it whole after the last safe point is in it too, and
    the reindexer will recover it. Not finished when the new file cannot be written (the same
    fault): ``scripts/reindex.py`` finishes it later and finds the same states.
    Raises InputError when the file cannot be read as an MCAP file."""
    from evoscen_sim.errors import HostFault

    path = _mcap_of(Path(bag_dir))
    contents = _read(path)
    result = _result(path, contents)
    try:
        _rewrite(path, contents, result, keep_original=False)
    except (OSError, InputError, HostFault):
        return result.steps, False
    return result.steps, True
