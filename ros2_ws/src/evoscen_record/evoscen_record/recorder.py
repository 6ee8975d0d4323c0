"""The rosbag2 (MCAP storage) bag writer :class:`BagRecorder`, without rosbag2.

The PyPI ROS 2 wheels lack rosbag2, so :class:`BagRecorder` writes the bag itself with
the low-level ``mcap`` writer. It stores *already serialized* CDR bytes (as an rclpy
``raw=True`` subscription hands them over, or as
``rclpy.serialization.serialize_message`` gives them in-process), so recording never
deserializes. The result is what ``ros2 bag record -s mcap`` (Jazzy) produces:

* a directory ``<bag_dir>/`` with ``metadata.yaml`` (rosbag2 format, version 9,
  :mod:`evoscen_record.metadata_yaml`) and one file ``<bag_dir>/<bag_dir.name>_0.mcap``
  (:mod:`evoscen_record.bag_file`);
* MCAP profile ``ros2``; one schema per message type, encoding ``ros2msg``, data = the
  concatenated message definition (:mod:`evoscen_record.schemas`); one channel per
  topic, message encoding ``cdr``, channel metadata ``offered_qos_profiles`` (YAML
  string) and ``topic_type_hash`` (``RIHS01_...``);
* chunked (default 1 MiB, and at most 1 s of log time per chunk, each closed chunk handed to
  the OS at once: a killed recorder leaves every closed chunk readable, see
  ``scripts/reindex.py``) and compressed (default zstd) chunks with message indexes,
  and a summary section (schemas, channels, statistics, chunk indexes, metadata
  index, summary offsets), so ``ros2 bag info/play``, Foxglove, ``mcap`` CLI,
  ``mcap_ros2`` and ``rosbags`` all open it;
* a ``rosbag2`` MCAP metadata record holding ``serialized_metadata`` (the same
  information as ``metadata.yaml``), as rosbag2 Jazzy writes, so the ``.mcap`` alone
  is self-describing.

Determinism: nothing depends on the wall clock, the host or the library's version
string; times are the simulation times passed in. Identical calls give
byte-identical ``.mcap`` and ``metadata.yaml``. Every message is canonicalized by default
(:class:`~evoscen_record.canonical_cdr.CanonicalCdr`: CDR padding zeroed); pass
``canonicalize=False`` to store the bytes as given (faster, not reproducible).

:func:`evoscen_record.bag_reader.open_bag_reader` iterates over the raw messages of a bag (for
offline evaluation and replay).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from types import TracebackType
from typing import Any

from mcap.writer import Writer

from evoscen_contract.contract import TOPIC_WORLD as _WORLD_TOPIC
from evoscen_contract.topics import TopicSpec
from evoscen_record.bag_channels import COMPRESSIONS, TopicState, check_arguments, register_topics
from evoscen_record.bag_file import BagFile, prepare_bag_dir
from evoscen_record.canonical_cdr import CanonicalCdr
from evoscen_record.mcap_internals import ChunkMessages, FastMessages, count_messages
from evoscen_record.metadata_yaml import bagfile_information, dump_metadata_yaml
from evoscen_record.schemas import message_definition
from evoscen_sim.errors import HostFault, InputError

#: MCAP header ``library`` string, in every bag: version-free, so that bags stay byte-identical across
#: library upgrades that do not change the encoding; it keeps the recorder's former module path for the same reason.
LIBRARY: str = "evoscen_eval.recorder (mcap-python)"
#: MCAP header profile of rosbag2 bags.
PROFILE: str = "ros2"
#: Default chunk size (bytes, uncompressed).
DEFAULT_CHUNK_SIZE: int = 1024 * 1024
#: Default longest span of a chunk in log time (= simulation time), ns: a chunk is closed and
#: handed to the OS once a message comes 1 s (simulated) or more after the chunk's first
#: message, so a recorder killed with SIGKILL loses at most about 1 s of simulated time of the
#: messages it had written (see docs/recording.md). Log time, not wall time: chunk boundaries
#: depend only on the messages, so both runners still write byte-identical bags.
DEFAULT_CHUNK_DURATION_NS: int = 1_000_000_000

class BagRecorder:
    """Write a rosbag2 bag directory (MCAP storage) from serialized CDR messages.

    Usage::

        with BagRecorder(Path("runs/bag"), CONTRACT) as bag:
            bag.write("/evoscen/world", cdr_bytes, log_time_ns=t_ns)
            bag.write_message("/clock", clock_message(t_ns), t_ns)

    All topics are declared up front (``topics``); their schemas and channels are
    registered at construction, in the given order (types deduplicated, first
    appearance wins), so the file layout depends only on the arguments and the
    messages written. Topics without messages still appear in the metadata (count 0).

    Args:
        bag_dir: bag directory to create; must not exist or be an empty directory.
        topics: contract entries of the topics to record (unique names).
        compression: chunk compression, ``"zstd"`` (default), ``"lz4"`` or ``"none"``.
        chunk_size: target uncompressed chunk size in bytes (default 1 MiB).
        chunk_duration_ns: longest log-time span of a chunk (default 1 s): a message with a log
            time this much or more after the open chunk's first message closes that chunk first
            and flushes it to the OS (0 = no time bound, size only).
        canonicalize: zero the CDR padding of every message (default True; needed for
            byte-identical bags, see the module docstring).
        metadata: MCAP metadata records ``{name: {key: value}}`` written right after the
            channels, before any message (evoscen records the resolved scenario
            configuration, see :mod:`evoscen_record.scenario_record`).
        fast_writes: write messages and message indexes with one ``pack`` each
            (:class:`FastMessages`; default) instead of the mcap library's own method: the
            same bytes; False for the library's path (``scripts/bench_recording.py`` compares).
        chunk_writes: with ``fast_writes``, keep the open chunk in the recorder and write it with
            a few operations per chunk (:class:`ChunkMessages`; default): the same bytes; False
            for :class:`FastMessages` alone (the tests compare the three paths).

    Raises:
        InputError: ``bag_dir`` exists and is not an empty directory, or cannot be
            created/written (message names the directory); bad ``compression`` or
            ``chunk_size``; duplicate topic names; a type whose definition is not
            installed.
    """

    def __init__(
        self,
        bag_dir: Path | str,
        topics: Sequence[TopicSpec],
        *,
        compression: str = "zstd",
        chunk_size: int = DEFAULT_CHUNK_SIZE,
        chunk_duration_ns: int = DEFAULT_CHUNK_DURATION_NS,
        canonicalize: bool = True,
        metadata: Mapping[str, Mapping[str, str]] | None = None,
        file_name: str | None = None,
        fast_writes: bool = True,
        chunk_writes: bool = True,
        finish_after_fault: Callable[[Path], tuple[int, bool]] | None = None,
    ) -> None:
        self.bag_dir: Path = Path(bag_dir)
        check_arguments(compression, chunk_size, chunk_duration_ns, topics)
        self._chunk_duration_ns = chunk_duration_ns
        self._chunk_start_ns: int | None = None  # log time of the open chunk's first message
        # Resolve all definitions before touching the disk (fail early, leave nothing).
        definitions = {spec.type_name: message_definition(spec.type_name) for spec in topics}
        self._canonical: CanonicalCdr | None = (
            CanonicalCdr(list(definitions)) if canonicalize else None
        )

        prepare_bag_dir(self.bag_dir)
        self.file_name: str = file_name or f"{self.bag_dir.name}_0.mcap"
        self.mcap_path: Path = self.bag_dir / self.file_name
        self.metadata_path: Path = self.bag_dir / "metadata.yaml"
        self._fault: HostFault | None = None
        self._fault_finisher = finish_after_fault
        """Finishes the bag directory from its complete chunks after a fault and returns (the world
        states in it, whether it was finished) (``evoscen_record.reindex.finish_bag``; None: leave
        it for ``scripts/reindex.py``).
        Passed in, so that the recorder does not import the reindexer that imports it."""
        self._safe_counts: dict[str, int] = {}
        try:
            self._stream: BagFile = BagFile(self.mcap_path, self)
        except OSError as exc:
            raise InputError(
                f"bag directory {str(self.bag_dir)!r}: cannot create {self.file_name}: "
                f"{exc.strerror or exc}"
            ) from None

        self._writer = Writer(
            self._stream,
            chunk_size=chunk_size,
            compression=COMPRESSIONS[compression],
        )
        self._writer.start(profile=PROFILE, library=LIBRARY)
        self._topics: dict[str, TopicState] = register_topics(self._writer, topics, definitions)
        self._chunk: ChunkMessages | None = None
        if fast_writes and chunk_writes and ChunkMessages.usable(self._writer):
            # after the channels: the library writes schemas and channels into its open chunk too
            self._chunk = ChunkMessages(self._writer)
            self._add_message = self._chunk.add
        elif fast_writes and FastMessages.usable(self._writer):
            self._add_message = FastMessages(self._writer).add
        else:
            self._add_message = self._writer.add_message
        for name, record in (metadata or {}).items():
            self._writer.add_metadata(name, {str(k): str(v) for k, v in record.items()})
        self._start_ns: int | None = None
        self._end_ns: int | None = None
        self._message_count = 0
        self._closed = False

    # ------------------------------------------------------------------ faults of the host

    def _on_safe_point(self) -> None:
        """Every message counted so far is on disk: note the counts (what a cut-back bag holds)."""
        topics = getattr(self, "_topics", None)
        if topics is not None:
            self._safe_counts = {name: st.message_count for name, st in topics.items()}

    def _fault_of(self, exc: OSError, path: Path) -> HostFault:
        """The first fault of the host: noted (nothing more is written), the file cut back."""
        if self._fault is None:
            self._fault = HostFault.of(exc, path, bag_dir=self.bag_dir)
            self._stream.cut_back()
        return self._fault

    @property
    def fault(self) -> HostFault | None:
        """The fault of the host that stopped this bag's writes (None if none)."""
        return self._fault

    def _finish_after_fault(self) -> None:
        """After a fault: finish the bag from its complete chunks if there is room (the
        reindexer's way), else leave it cut back to them for ``scripts/reindex.py``."""
        fault = self._fault
        self._stream.close()
        fault.steps = self._safe_counts.get(_WORLD_TOPIC, 0)
        if not self.mcap_path.exists():
            fault.bag_state = "lost"
            return
        if self._stream.on_disk == 0:  # not even the first chunk reached the disk
            fault.bag_state = "empty"
            return
        fault.bag_state = "reindex"
        if self._fault_finisher is None:
            return
        try:
            steps, finished = self._fault_finisher(self.bag_dir)
        except (OSError, InputError, HostFault):  # unreadable: what was flushed is in it, if anything
            if self._stream.good == 0:  # a first chunk cut short that could not be cut off
                fault.bag_state = "empty"
            return
        # counted in the file: where it could not be cut back, a chunk that reached it whole after
        # the last safe point is in it too (docs/recording.md, "Faults of the host")
        fault.steps = steps
        if finished:
            fault.bag_state = "finished"

    # ------------------------------------------------------------------ writing

    @property
    def closed(self) -> bool:
        """True once :meth:`close` has run."""
        return self._closed

    @property
    def message_count(self) -> int:
        """Number of messages written so far (all topics)."""
        return self._message_count

    def topic_message_counts(self) -> dict[str, int]:
        """Return ``{topic: messages written}`` in declaration order."""
        return {name: st.message_count for name, st in self._topics.items()}

    def write(
        self,
        topic: str,
        data: bytes | bytearray | memoryview,
        log_time_ns: int,
        publish_time_ns: int | None = None,
        *,
        canonical: bool = False,
    ) -> None:
        """Append one serialized (CDR) message.

        Args:
            topic: a topic declared at construction.
            data: the message serialized as CDR (with its 4-byte encapsulation header),
                e.g. from a ``raw=True`` subscription or ``serialize_message``.
            log_time_ns: record time (ns); evoscen uses the simulation time of the
                message (its header stamp), never the wall clock.
            publish_time_ns: publish time (ns); defaults to ``log_time_ns``.
            canonical: the caller guarantees ``data`` is already canonical CDR (zero
                padding, e.g. from :mod:`evoscen_contract.cdr`): stored as given.

        Raises:
            ValueError: unknown topic, negative time, the recorder is closed, or (with
                ``canonicalize``) ``data`` does not decode as the topic's type.
        """
        if self._closed:
            raise ValueError(f"BagRecorder {str(self.bag_dir)!r}: write after close")
        state = self._topics.get(topic)
        if state is None:
            raise ValueError(
                f"BagRecorder {str(self.bag_dir)!r}: topic {topic!r} was not declared "
                f"(declared: {list(self._topics)})"
            )
        log_time = int(log_time_ns)
        publish_time = log_time if publish_time_ns is None else int(publish_time_ns)
        if log_time < 0 or publish_time < 0:
            raise ValueError(
                f"BagRecorder: times must be >= 0 ns (log {log_time}, publish {publish_time})"
            )
        if self._canonical is not None and not canonical:
            try:
                payload = self._canonical(state.spec.type_name, data)
            except ValueError as exc:
                raise ValueError(f"BagRecorder: topic {topic!r}: {exc}") from None
        else:
            payload = bytes(data)
        if self._chunk_duration_ns:
            self._time_bound(log_time)
        state.message_count += 1
        self._add_message(state.channel_id, log_time, payload, publish_time,
                          state.message_count)  # sequence: a per-channel counter, 1-based
        self._message_count += 1
        self._start_ns = log_time if self._start_ns is None else min(self._start_ns, log_time)
        self._end_ns = log_time if self._end_ns is None else max(self._end_ns, log_time)

    def write_many(self, messages: Sequence[tuple[int, str, bytes | bytearray | memoryview, bool]]) -> None:
        """:meth:`write` each ``(log_time_ns, topic, data, canonical)`` in turn (publish time = log
        time): the same file as that many calls, with the per-call work done once.

        Raises:
            ValueError: as :meth:`write`; the messages before the offending one are written.
        """
        if self._closed:
            raise ValueError(f"BagRecorder {str(self.bag_dir)!r}: write after close")
        if self._chunk is not None:
            self._write_queued([(t, 0, 0, topic, data, canonical) for t, topic, data, canonical in messages])
            return
        topics, add, duration = self._topics, self._add_message, self._chunk_duration_ns
        for log_time_ns, topic, data, canonical in messages:
            state = topics.get(topic)
            log_time = int(log_time_ns)
            if state is None or log_time < 0 or (self._canonical is not None and not canonical):
                self.write(topic, data, log_time, canonical=canonical)  # its checks and errors
                continue
            payload = bytes(data)
            if duration:
                self._time_bound(log_time)
            state.message_count += 1
            add(state.channel_id, log_time, payload, log_time, state.message_count)
            self._message_count += 1
            if self._start_ns is None or log_time < self._start_ns:
                self._start_ns = log_time
            if self._end_ns is None or log_time > self._end_ns:
                self._end_ns = log_time

    def _write_queued(self, messages: Sequence[tuple[int, int, int, str, Any, bool]]) -> None:
        """:meth:`write_many` of ``(log_time_ns, _, _, topic, data, canonical)``
        (:class:`~evoscen_record.ordered_bag.OrderedBag`'s queue entries) on the
        :class:`ChunkMessages` path, in one loop: the bookkeeping of
        :meth:`write` and of :meth:`ChunkMessages.add` for each message, written out here (a
        message that is not canonical ``bytes`` of a declared topic at an ``int`` time >= 0 goes
        through :meth:`write`, its checks and errors). The same file as :meth:`write` per message
        (tests compare)."""
        if self._closed:
            raise ValueError(f"BagRecorder {str(self.bag_dir)!r}: write after close")
        chunk = self._chunk
        st = chunk._st  # the writer's statistics, see ChunkMessages
        counts, indices = st.channel_message_counts, chunk._indices
        topics, duration, limit = self._topics, self._chunk_duration_ns, chunk._chunk_size
        head = ChunkMessages._HEAD.pack
        raw_ok = self._canonical is None
        # the open chunk's and the bag's running figures as locals, put back (``sync``) before anything
        # that reads them: closing a chunk, write(), the end; times as min / max, which order leaves alone
        pieces, size, count, c_start, c_end = chunk._pieces, chunk._size, chunk._count, chunk._start, chunk._end
        chunk_start = self._chunk_start_ns
        n = 0  # messages since the last sync
        lo = hi = 0
        k, total = 0, len(messages)
        while k < total:
            log_time, _, _, topic, data, canonical = messages[k]
            k += 1
            state = topics.get(topic)
            slow = state is None or type(log_time) is not int or log_time < 0 or type(data) is not bytes \
                or not (canonical or raw_ok)
            new_chunk = not slow and duration and chunk_start is not None and log_time - chunk_start >= duration
            if slow or new_chunk:
                chunk._pieces, chunk._size, chunk._count, chunk._start, chunk._end = pieces, size, count, c_start, c_end
                self._chunk_start_ns = chunk_start
                self._sync(st, n, lo, hi)
                n = 0
                if slow:
                    self.write(topic, data, log_time, canonical=canonical)
                else:
                    self._flush_chunk()  # close the chunk, write it out and hand it to the OS
                    self._chunk_start_ns = log_time
                pieces, size, count, c_start, c_end = chunk._pieces, chunk._size, chunk._count, chunk._start, chunk._end
                indices, chunk_start = chunk._indices, self._chunk_start_ns
                if slow:
                    continue
            elif duration and chunk_start is None:
                chunk_start = log_time
            state.message_count = seq = state.message_count + 1
            channel_id = state.channel_id
            if n == 0:
                lo = hi = log_time
            elif log_time < lo:
                lo = log_time
            elif log_time > hi:
                hi = log_time
            n += 1
            counts[channel_id] += 1
            if count == 0 or log_time < c_start:
                c_start = log_time
            if log_time > c_end:
                c_end = log_time
            index = indices.get(channel_id)
            if index is None:
                index = indices[channel_id] = []
            index += (log_time, size)
            count += 1
            pieces += (head(0x05, 22 + len(data), channel_id, seq, log_time, log_time), data)
            size += 31 + len(data)
            if size > limit:
                chunk._pieces, chunk._size, chunk._count, chunk._start, chunk._end = pieces, size, count, c_start, c_end
                self._sync(st, n, lo, hi)
                n = 0
                chunk.finalize()
                pieces, size, count, c_start, c_end = chunk._pieces, chunk._size, chunk._count, chunk._start, chunk._end
                indices = chunk._indices
        chunk._pieces, chunk._size, chunk._count, chunk._start, chunk._end = pieces, size, count, c_start, c_end
        self._chunk_start_ns = chunk_start
        self._sync(st, n, lo, hi)

    def write_parts(self, log_time_ns: int, messages: Sequence[tuple[str, Sequence[bytes]]]) -> None:
        """Write canonical messages all at ``log_time_ns`` (publish time = log time), in the order
        given, each as the pieces of its bytes: the file of ``write_many([(log_time_ns, topic,
        b"".join(parts), True), ...])`` (tests compare), the pieces going into the open chunk as
        they are and the 1-s rule and the checks done once (the in-process runner's steps).

        Raises:
            ValueError: as :meth:`write_many`.
        """
        chunk = self._chunk
        topics = self._topics
        if chunk is None or self._closed or type(log_time_ns) is not int or log_time_ns < 0 \
                or not all(topic in topics for topic, _ in messages):
            self.write_many([(log_time_ns, topic, b"".join(parts), True) for topic, parts in messages])
            return
        t = log_time_ns
        if self._chunk_duration_ns:
            self._time_bound(t)
        st = chunk._st  # the writer's statistics, see ChunkMessages
        counts, head, limit = st.channel_message_counts, ChunkMessages._HEAD.pack, chunk._chunk_size
        pieces, indices, size, count = chunk._pieces, chunk._indices, chunk._size, chunk._count
        n = 0
        for topic, parts in messages:
            if count == 0 or t < chunk._start:
                chunk._start = t
            if t > chunk._end:
                chunk._end = t
            state = topics[topic]
            state.message_count = seq = state.message_count + 1
            channel_id = state.channel_id
            length = sum(map(len, parts))
            counts[channel_id] += 1
            index = indices.get(channel_id)
            if index is None:
                index = indices[channel_id] = []
            index += (t, size)
            count += 1
            n += 1
            pieces.append(head(0x05, 22 + length, channel_id, seq, t, t))
            pieces += parts
            size += 31 + length
            if size > limit:
                chunk._size, chunk._count = size, count
                self._sync(st, n, t, t)
                n = 0
                chunk.finalize()
                pieces, indices, size, count = chunk._pieces, chunk._indices, chunk._size, chunk._count
        chunk._size, chunk._count = size, count
        self._sync(st, n, t, t)

    def _time_bound(self, log_time: int) -> None:
        """The time bound of a chunk (``chunk_duration_ns``, not 0): a message ``log_time`` that
        comes that long or more after the open chunk's first message closes that chunk first."""
        if self._chunk_start_ns is None:
            self._chunk_start_ns = log_time
        elif log_time - self._chunk_start_ns >= self._chunk_duration_ns:
            self._flush_chunk()  # close the chunk, write it out and hand it to the OS
            self._chunk_start_ns = log_time

    def _sync(self, st, n: int, lo: int, hi: int) -> None:  # mcap's Statistics
        """Count ``n`` messages written with log times ``lo``..``hi`` in the writer's statistics and
        the bag's own (what :meth:`ChunkMessages.add` and :meth:`write` count one at a time)."""
        if n:
            count_messages(st, n, lo, hi)
            self._message_count += n
            if self._start_ns is None or lo < self._start_ns:
                self._start_ns = lo
            if self._end_ns is None or hi > self._end_ns:
                self._end_ns = hi

    def write_message(self, topic: str, msg: Any, log_time_ns: int) -> None:
        """Serialize an rclpy message (``serialize_message``) and :meth:`write` it.

        Raises:
            ValueError: as :meth:`write`, or ``msg`` is not of the topic's message class.
        """
        from rclpy.serialization import serialize_message

        state = self._topics.get(topic)
        if state is not None and not isinstance(msg, state.spec.msg_class):
            raise ValueError(
                f"BagRecorder: topic {topic!r} carries {state.spec.type_name}, "
                f"got {type(msg).__module__}.{type(msg).__name__}"
            )
        self.write(topic, serialize_message(msg), log_time_ns)

    def flush(self) -> None:
        """Finish the current chunk and flush it to disk (smaller chunks compress worse)."""
        if not self._closed:
            self._flush_chunk()
            self._chunk_start_ns = None

    def _flush_chunk(self) -> None:
        """Close the open chunk, write it out and flush the stream (the library's ``flush``)."""
        if self._chunk is not None:
            self._chunk.finalize()
        self._writer.flush()

    # ------------------------------------------------------------------ closing

    def metadata(self) -> dict[str, Any]:
        """Return the rosbag2 ``metadata.yaml`` content (as written by :meth:`close`;
        :func:`~evoscen_record.metadata_yaml.bagfile_information`)."""
        return bagfile_information(((st.spec, st.message_count) for st in self._topics.values()),
                                   self.file_name, self._start_ns, self._end_ns, self._message_count)

    def close(self) -> None:
        """Finish the bag: summary section, then ``metadata.yaml``. Idempotent.

        Writes the ``rosbag2`` metadata record, the last chunk with its message
        indexes, and the summary (schemas, channels, statistics, chunk indexes,
        metadata index, summary offsets) and footer; closes the file; writes
        ``metadata.yaml`` (rosbag2 version 9; chunk compression is MCAP-internal, so
        ``compression_format``/``compression_mode`` are empty, as with rosbag2's
        storage-level compression).
        """
        if self._closed:
            return
        self._closed = True
        if self._fault is not None:  # raised already where the write failed
            self._finish_after_fault()
            return
        info_text, meta_text = dump_metadata_yaml(self.metadata()["rosbag2_bagfile_information"])
        try:
            self._writer.add_metadata("rosbag2", {"serialized_metadata": info_text})
            if self._chunk is not None:
                self._chunk.finalize()  # where the library's finish() writes its open chunk
                self._stream.flush()  # every message is on disk: the summary is all that is left
            self._writer.finish()
            self._stream.flush()
        except HostFault:
            self._finish_after_fault()
            raise
        finally:
            self._stream.close()
        try:
            self.metadata_path.write_text(meta_text, encoding="utf-8")
        except OSError as exc:
            # the MCAP file is complete: only metadata.yaml is missing (the reindexer writes it)
            self._fault = HostFault.of(exc, self.metadata_path, bag_dir=self.bag_dir,
                                       steps=self._topics[_WORLD_TOPIC].message_count
                                       if _WORLD_TOPIC in self._topics else 0)
            self._fault.bag_state = "reindex" if self.mcap_path.exists() else "lost"
            raise self._fault from None

    def __enter__(self) -> BagRecorder:
        """Return self (the bag is already open)."""
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        """Close the bag, also on error, so a finished bag is left in every case."""
        self.close()

