"""The one place evoscen reaches into the ``mcap`` library's private internals (mcap 1.6.0, pinned).

:class:`~evoscen_record.recorder.BagRecorder` writes its messages, and with :class:`ChunkMessages` its
chunks, itself instead of through ``mcap.writer.Writer.add_message``: the library packs each field
with its own call (~15 µs per message, half the cost of recording a step). To do that it reads and
updates the writer's name-mangled attributes (:data:`WRITER_ATTRIBUTES`), its chunk builder
(``mcap._chunk_builder.ChunkBuilder``, :data:`CHUNK_BUILDER_ATTRIBUTES`) and statistics
(:data:`STATISTICS_FIELDS`), and writes the same records the library writes, byte for
byte (tests/test_bag_hashes.py; ``test_recorder_paths.py`` compares the three write paths).

Each fast path is used only where :meth:`FastMessages.usable` / :meth:`ChunkMessages.usable` find
the writer they were written against; any other writer gets the library's own method (the same
bytes, slower). ``test_mcap_internals.py`` fails when the installed mcap is not the pinned
version or lacks one of the private members used (:func:`missing_internals`), so an upgrade that
changes them is seen at once instead of silently slowing recording down.
"""

from __future__ import annotations

import struct

from mcap._chunk_builder import ChunkBuilder
from mcap.records import ChunkIndex, MessageIndex
from mcap.writer import CompressionType, Writer

MCAP_VERSION = "1.6.0"
"""The mcap release these classes were written against (``requirements-runtime.txt`` pins it)."""

WRITER_ATTRIBUTES = ("_Writer__statistics", "_Writer__chunk_builder", "_Writer__chunk_size",
                     "_Writer__maybe_finalize_chunk", "_Writer__enable_crcs", "_Writer__enable_data_crcs",
                     "_Writer__compression", "_Writer__chunk_indices", "_Writer__index_types", "_Writer__stream")
"""The private attributes of ``mcap.writer.Writer`` read or updated here."""

CHUNK_BUILDER_ATTRIBUTES = ("record_writer", "num_messages", "message_start_time", "message_end_time",
                            "message_indices")
"""The attributes of the writer's ``mcap._chunk_builder.ChunkBuilder`` read or updated here."""

RECORD_WRITER_ATTRIBUTES = ("_buffer", "end")
"""The attributes of the chunk builder's ``record_writer`` (``mcap.data_stream.RecordBuilder``) used here."""

STATISTICS_FIELDS = ("message_count", "message_start_time", "message_end_time", "channel_message_counts",
                     "chunk_count")
"""The fields of the writer's ``mcap.records.Statistics`` updated here."""

RECORD_METHODS = (MessageIndex, ChunkIndex)
"""The record classes whose ``write(stream)`` the library calls and :class:`FastMessageIndex` /
:class:`FastChunkIndex` replace."""


def missing_internals(writer: Writer) -> list[str]:
    """The private parts this module uses that ``writer`` lacks (empty: all there): the attributes of
    :data:`WRITER_ATTRIBUTES`, then the chunk builder's type and :data:`CHUNK_BUILDER_ATTRIBUTES`,
    its record writer's :data:`RECORD_WRITER_ATTRIBUTES`, the statistics' :data:`STATISTICS_FIELDS`
    and the ``write`` method of :data:`RECORD_METHODS`, each named as ``Owner.member``."""
    missing = [name for name in WRITER_ATTRIBUTES if not hasattr(writer, name)]
    cb = getattr(writer, "_Writer__chunk_builder", None)
    if cb is not None:
        if type(cb) is not ChunkBuilder:
            missing.append("_Writer__chunk_builder: a mcap._chunk_builder.ChunkBuilder")
        missing += [f"ChunkBuilder.{name}" for name in CHUNK_BUILDER_ATTRIBUTES if not hasattr(cb, name)]
        rw = getattr(cb, "record_writer", None)
        if rw is not None:
            missing += [f"ChunkBuilder.record_writer.{name}" for name in RECORD_WRITER_ATTRIBUTES
                        if not hasattr(rw, name)]
    st = getattr(writer, "_Writer__statistics", None)
    if st is not None:
        missing += [f"Statistics.{name}" for name in STATISTICS_FIELDS if not hasattr(st, name)]
    missing += [f"{cls.__name__}.write" for cls in RECORD_METHODS if not callable(vars(cls).get("write"))]
    return missing


def count_messages(st, n: int, lo: int, hi: int) -> None:  # the writer's mcap.records.Statistics
    """Count ``n`` messages with log times ``lo``..``hi`` in the writer's statistics ``st`` (the
    summary's): the message count and the first and last log time; the per-channel counts are the
    caller's (:func:`count_message` for one message)."""
    if st.message_count == 0 or lo < st.message_start_time:
        st.message_start_time = lo
    if hi > st.message_end_time:
        st.message_end_time = hi
    st.message_count += n


def count_message(st, channel_id: int, log_time: int) -> None:  # the writer's mcap.records.Statistics
    """Count one message of ``channel_id`` at ``log_time`` in the writer's statistics ``st``, as the
    library's ``add_message`` does (both fast paths' ``add``)."""
    count_messages(st, 1, log_time, log_time)
    st.channel_message_counts[channel_id] += 1


class FastMessageIndex(MessageIndex):
    """``MessageIndex`` whose :meth:`write` packs the record in one call (mcap 1.6 writes each of
    the 2n numbers with its own ``pack`` and buffer write): opcode 0x07, record length, channel
    id, records length = 16 n, then n (log time, offset) pairs — the same bytes."""

    def write(self, stream) -> None:  # mcap's RecordBuilder
        n = len(self.records)
        flat = [x for pair in self.records for x in pair]
        stream.write(struct.pack(f"<BQHI{2 * n}Q", 0x07, 6 + 16 * n, self.channel_id, 16 * n, *flat))


class FastChunkIndex(ChunkIndex):
    """``ChunkIndex`` whose :meth:`write` packs the record in two calls (mcap 1.6 writes its ~12 + 2n
    fields one ``pack`` and buffer write at a time; a run's summary holds one per chunk, ~300 for
    3,000 steps): opcode 0x08, record length, start and end time, chunk offset and length, the
    message index offsets (channel id, offset) with their byte length, index length,
    compression, sizes — the same bytes."""

    def write(self, stream) -> None:  # mcap's RecordBuilder
        offsets = self.message_index_offsets
        n = len(offsets)
        name = self.compression.encode()
        flat = [x for item in offsets.items() for x in item]
        body = struct.pack(f"<QQQQI{'HQ' * n}QI", self.message_start_time, self.message_end_time,
                           self.chunk_start_offset, self.chunk_length, 10 * n, *flat, self.message_index_length,
                           len(name))
        tail = struct.pack("<QQ", self.compressed_size, self.uncompressed_size)
        stream.write(b"".join((struct.pack("<BQ", 0x08, len(body) + len(name) + 16), body, name, tail)))


class FastMessages:
    """``mcap.writer.Writer.add_message`` (mcap 1.6, pinned) in a few Python operations.

    The library builds a ``Message`` record object and writes its six fields one ``struct.pack``
    and one buffer write at a time, ~15 µs per message — half the cost of recording a step.
    :meth:`add` does the same bookkeeping on the writer's own statistics and chunk builder and
    writes the record with one ``pack``: the same bytes in the same places (the file is then
    finished by the library as before; tests/test_bag_hashes.py and the recorder's tests compare
    whole bags). Used only when the writer is the one this was written against
    (:meth:`usable`); otherwise the library's method.
    """

    _HEAD = struct.Struct("<BQHIQQ")  # opcode, record length, channel id, sequence, log time, publish time
    _MESSAGE = 0x05
    _FIELDS = 22  # bytes of the fixed fields after the record header

    @staticmethod
    def usable(writer: Writer) -> bool:
        cb = getattr(writer, "_Writer__chunk_builder", None)
        return type(cb) is ChunkBuilder and hasattr(writer, "_Writer__statistics") \
            and hasattr(writer, "_Writer__chunk_size") and hasattr(cb, "record_writer")

    def __init__(self, writer: Writer) -> None:
        self._st = writer._Writer__statistics  # see the class docstring
        self._cb: ChunkBuilder = writer._Writer__chunk_builder
        self._chunk_size: int = writer._Writer__chunk_size
        self._finalize = writer._Writer__maybe_finalize_chunk

    def add(self, channel_id: int, log_time: int, data: bytes, publish_time: int, sequence: int) -> None:
        cb = self._cb
        count_message(self._st, channel_id, log_time)
        if cb.num_messages == 0 or log_time < cb.message_start_time:
            cb.message_start_time = log_time
        if log_time > cb.message_end_time:
            cb.message_end_time = log_time
        index = cb.message_indices.get(channel_id)
        if index is None:
            index = cb.message_indices[channel_id] = FastMessageIndex(channel_id=channel_id, records=[])
        buf = cb.record_writer._buffer  # a new BytesIO after every chunk
        index.records.append((log_time, buf.tell()))
        cb.num_messages += 1
        buf.write(self._HEAD.pack(self._MESSAGE, self._FIELDS + len(data), channel_id, sequence, log_time,
                                  publish_time))
        buf.write(data)
        if buf.tell() > self._chunk_size:
            self._finalize()


class ChunkMessages:
    """The open chunk kept by the recorder itself, written with a few Python operations per chunk.

    :class:`FastMessages` writes each message record into mcap's chunk builder; this class
    keeps the chunk's records as a list of byte strings (one ``pack`` per message header), their
    offsets and per-channel index entries, and at :meth:`finalize` writes what the library's
    ``Writer.__finalize_chunk`` (mcap 1.6, pinned) writes — the chunk record (records joined,
    compressed with a zstd compressor kept for the run, CRC-32 of the uncompressed records),
    then one message index record per channel in first-appearance order — and registers the
    chunk's index and statistics in the writer, which finishes the file (summary) as before.
    The same bytes in the same places (tests/test_bag_hashes.py, and a test comparing all three
    write paths). The schema and channel records the library writes into its open chunk at
    registration are taken over at construction (so construct it after registering channels).
    A message making the open chunk larger than ``chunk_size`` closes it after that message, as
    the library does. Used only when the writer is the one this was written
    against (:meth:`usable`).
    """

    _HEAD = FastMessages._HEAD
    _INDEX_HEAD = struct.Struct("<BQHI")  # opcode 0x07, record length, channel id, records length
    _CHUNK_HEAD = struct.Struct("<BQQQQI")  # opcode 0x06, record length, start, end, size, crc
    _NAMES = {CompressionType.ZSTD: "zstd", CompressionType.LZ4: "lz4", CompressionType.NONE: ""}

    @staticmethod
    def usable(writer: Writer) -> bool:
        from mcap.writer import IndexType

        return FastMessages.usable(writer) \
            and getattr(writer, "_Writer__enable_crcs", None) is True \
            and getattr(writer, "_Writer__enable_data_crcs", None) is False \
            and getattr(writer, "_Writer__compression", None) in ChunkMessages._NAMES \
            and isinstance(getattr(writer, "_Writer__chunk_indices", None), list) \
            and bool(getattr(writer, "_Writer__index_types", 0) & IndexType.MESSAGE) \
            and writer._Writer__chunk_builder.num_messages == 0

    def __init__(self, writer: Writer) -> None:
        import zlib

        self._st = writer._Writer__statistics  # see the class docstring
        self._chunk_size: int = writer._Writer__chunk_size
        self._chunk_indices: list = writer._Writer__chunk_indices
        self._stream = writer._Writer__stream
        compression = writer._Writer__compression
        self._compression_name = self._NAMES[compression]
        if compression == CompressionType.ZSTD:
            import zstandard

            self._compress = zstandard.ZstdCompressor(level=3).compress  # = zstandard.compress(data)
        elif compression == CompressionType.LZ4:
            import lz4.frame

            self._compress = lz4.frame.compress
        else:
            self._compress = bytes
        self._crc32 = zlib.crc32
        self._reset()
        # the schema and channel records the library put into its (message-less) open chunk
        # come first in this chunk, as they would in the library's
        opened = writer._Writer__chunk_builder.record_writer.end()
        if opened:
            self._pieces.append(bytes(opened))
            self._size = len(opened)

    def _reset(self) -> None:
        self._pieces: list[bytes] = []
        self._size = 0  # bytes of the records so far
        self._indices: dict[int, list[int]] = {}  # channel -> [log time, offset, log time, offset, ...]
        self._start = 0
        self._end = 0
        self._count = 0

    def add(self, channel_id: int, log_time: int, data: bytes, publish_time: int, sequence: int) -> None:
        count_message(self._st, channel_id, log_time)
        if self._count == 0 or log_time < self._start:
            self._start = log_time
        if log_time > self._end:
            self._end = log_time
        self._indices.setdefault(channel_id, []).extend((log_time, self._size))
        self._count += 1
        self._pieces += (self._HEAD.pack(0x05, 22 + len(data), channel_id, sequence, log_time, publish_time), data)
        self._size += 31 + len(data)
        if self._size > self._chunk_size:
            self.finalize()

    def finalize(self) -> None:
        """Write the open chunk (if it holds a message) and its message indexes to the stream."""
        if self._count == 0:
            return
        self._st.chunk_count += 1
        records = b"".join(self._pieces)
        compressed = self._compress(records)
        name = self._compression_name.encode()
        stream = self._stream
        chunk_start = stream.tell()
        head = self._CHUNK_HEAD.pack(0x06, 8 + 8 + 8 + 4 + 4 + len(name) + 8 + len(compressed), self._start,
                                     self._end, len(records), self._crc32(records))
        stream.write(b"".join((head, struct.pack("<I", len(name)), name, struct.pack("<Q", len(compressed)),
                               compressed)))
        chunk_length = stream.tell() - chunk_start
        index_start = stream.tell()
        offsets = {}
        parts = []
        at = 0
        for channel_id, flat in self._indices.items():
            offsets[channel_id] = index_start + at
            n = 8 * len(flat)
            parts.append(self._INDEX_HEAD.pack(0x07, 6 + n, channel_id, n))
            parts.append(struct.pack(f"<{len(flat)}Q", *flat))
            at += 15 + n
        stream.write(b"".join(parts))
        self._chunk_indices.append(FastChunkIndex(
            message_start_time=self._start, message_end_time=self._end, chunk_start_offset=chunk_start,
            chunk_length=chunk_length, message_index_offsets=offsets, message_index_length=at,
            compression=self._compression_name, compressed_size=len(compressed), uncompressed_size=len(records)))
        self._reset()
