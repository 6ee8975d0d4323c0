"""Recording off the simulation's core: an in-process run's bag written by a forked writer process.

The in-process runner can write its bag on its own thread (:class:`~evoscen_record.step_recorder.StepRecorder`,
``bag_writer="inline"``) or hand it to a second process (:class:`ProcessRecorder`,
``bag_writer="process"``; docs/recording.md, "In-process runs: the bag written inline or by a writer process"). With the process writer the
run's step only copies what the bag needs — the world's state arrays (:meth:`World.state_arrays
<evoscen_sim.physics.world.World.state_arrays>`), the command tables, the events — into shared memory and
notes each call in a journal; the writer process, forked at the start of the run, replays the
journal through the same :class:`~evoscen_record.step_recorder.StepRecorder` the inline path uses. The
world table's columns are rebuilt by :func:`evoscen_sim.physics.world.state_columns`, the one definition
:meth:`World.columns <evoscen_sim.physics.world.World.columns>` uses, so the bag is byte-identical to the
inline path's (tests/test_recording_paths.py compares the files).

The shared memory is ``slots`` batches of ``steps_per_slot`` steps each. The run fills a batch,
sends its journal through a pipe and goes on with a free batch; the writer replays a batch and
hands it back. The run waits only when every batch is still being written (the writer is slower
than the run) and at the end, when the bag is closed. Errors: the writer's error (a bag directory
that cannot be created, a full disk) is raised in the run as the same exception; a fault of the
host (:class:`~evoscen_sim.errors.HostFault`) is flagged in shared memory, so the run stops at its
next step boundary, and comes once the writer has finished the bag from what reached the disk
(or cut it back for the reindexer); a writer that dies is a one-line :class:`BagWriterError`. The writer ignores Ctrl-C (SIGINT goes to the whole
process group): the run finishes the bag (``run_end`` of kind ``interrupted``) through it, as the
inline path does; if the run itself goes away, the writer finishes the bag with what it received.
"""

from __future__ import annotations

import mmap
import multiprocessing
import os
import pickle
import signal
from pathlib import Path

import numpy as np
from evoscen_sim.errors import HostFault
from evoscen_sim.physics.world import STATE_FLOATS, STATE_INTS, state_columns

from .recording_plan import RecordingPlan
from .step_recorder import StepRecorder

WRITERS = ("auto", "inline", "process")
"""``bag_writer`` values of :func:`evoscen_bringup.inprocess.run_inprocess` (docs/recording.md)."""


class BagWriterError(RuntimeError):
    """The writer process ended without finishing the bag (one line: which bag, how it ended)."""


def resolve_writer(bag_writer: str) -> str:
    """``"inline"`` or ``"process"`` for ``bag_writer``; ``"auto"`` is the process writer when this
    process may use more than one CPU, the platform forks and this is not a daemonic process,
    else inline."""
    if bag_writer not in WRITERS:
        raise ValueError(f"bag_writer {bag_writer!r}: expected one of {', '.join(WRITERS)}")
    if bag_writer != "auto":
        return bag_writer
    if "fork" not in multiprocessing.get_all_start_methods() or multiprocessing.current_process().daemon:
        return "inline"  # no fork, or a daemonic process (a pool's worker), which may not have children
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cpus = os.cpu_count() or 1
    return "process" if cpus > 1 else "inline"


def _shared(shape: tuple[int, ...], dtype) -> np.ndarray:
    """A zeroed array in anonymous shared memory (a fork's child sees the parent's writes)."""
    size = int(np.prod(shape)) * np.dtype(dtype).itemsize
    buf = mmap.mmap(-1, max(size, 1))  # MAP_SHARED | MAP_ANONYMOUS
    return np.ndarray(shape, dtype=dtype, buffer=buf)


class ProcessRecorder:
    """The in-process runner's recorder with the bag written by a forked process (module docstring).

    Same calls as :class:`~evoscen_record.step_recorder.StepRecorder` (``world``, ``state``,
    ``commands``, ``events``, ``close``, ``message_count``); ``world`` and ``state`` take the
    :class:`~evoscen_sim.physics.world.World` itself. Opened with the run's recording part
    (:class:`~evoscen_record.recording_plan.RecordingPlan`) and its world at step 0.
    """

    snapshots = True  # world/state read the World, not its columns
    slots = 4
    """Batches in shared memory (the run waits when all of them are with the writer)."""
    steps_per_slot = 128
    """Steps per batch: a pipe message and a hand-back per this many steps."""

    def __init__(self, bag_dir: Path, recording: RecordingPlan, world) -> None:
        from evoscen_contract import topics as T

        slots, steps_per_slot = self.slots, self.steps_per_slot

        self.T = T
        self.bag_dir = Path(bag_dir)
        self._topics = (T.COMMANDS_BV.name, T.COMMANDS_SUT.name)
        n, n_bv = world.n, recording.bv_count
        self._k = steps_per_slot
        # +1 row: a batch may hold the final state after its last full step (StepLoop._end)
        self._f = _shared((slots, steps_per_slot + 1, len(STATE_FLOATS), n), np.float64)
        self._i = _shared((slots, steps_per_slot + 1, len(STATE_INTS), n), np.int64)
        self._c = (_shared((slots, steps_per_slot + 1, 2, max(n_bv, 1)), np.float64),
                   _shared((slots, steps_per_slot + 1, 2, 1), np.float64))
        self._flag = _shared((1,), np.int8)  # set by the writer when it failed (checked every step)
        self._fault: BaseException | None = None
        _warm_up(recording, world)
        ctx = multiprocessing.get_context("fork")
        to_writer_r, self._to_writer = ctx.Pipe(duplex=False)
        self._from_writer, from_writer_w = ctx.Pipe(duplex=False)
        # daemon: should the run's process end without closing the bag, it does not wait for the writer
        self._proc = ctx.Process(target=_writer_main, name="evoscen-bag-writer", daemon=True,
                                 args=(to_writer_r, from_writer_w, (self._to_writer, self._from_writer),
                                       self.bag_dir, recording, world.road, self._f, self._i, self._c, self._topics,
                                       self._flag))
        self._proc.start()
        to_writer_r.close()
        from_writer_w.close()
        self._message_count = 0
        self._closed = False
        self._free = list(range(slots))
        self._expect("ready")
        self._slot = self._free.pop(0)
        self._journal: list[tuple] = []
        self._rows = 0  # state rows used in the open batch
        self._crows = [0, 0]  # command rows used, per command topic
        self._ids: list = [None, None]  # the ids last journaled, per command topic

    # ------------------------------------------------------------------ the run's side

    def world(self, world, cols, t_ns: int, *, roster: bool) -> None:
        """Copy the world's state into the open batch and journal ``/evoscen/world`` (+ roster);
        a writer that failed (a fault of the host) stops the run here, at the step boundary."""
        if self._flag[0]:
            self._writer_failed()
        if self._rows >= self._k:
            self._send_batch()
        floats, ints = world.state_arrays()
        row = self._rows
        self._f[self._slot, row] = floats
        self._i[self._slot, row] = ints
        self._rows = row + 1
        self._journal.append(("W", row, t_ns, roster))

    def state(self, world, cols, sut_index: int, step_index: int, t_ns: int) -> None:
        """Journal the rest of the state (from the row :meth:`world` copied)."""
        self._journal.append(("S", self._rows - 1, sut_index, step_index, t_ns))

    def bv_commands(self, ids, throttle, lane_change, t_ns: int) -> None:
        """The commands of all BVs; the writer splits them by BV node (``StepRecorder.bv_commands``)."""
        self.commands(self.T.COMMANDS_BV.name, ids, throttle, lane_change, t_ns)

    def commands(self, topic: str, ids, throttle, lane_change, t_ns: int) -> None:
        which = self._topics.index(topic)
        row = self._crows[which]
        if row > self._k:
            self._send_batch()
            row = 0
        table = self._c[which][self._slot, row]
        table[0, :len(throttle)] = throttle
        table[1, :len(lane_change)] = lane_change
        self._crows[which] = row + 1
        if ids is not self._ids[which]:  # the port passes the same ids array every step
            self._ids[which] = ids
            sent = np.array(ids)
        else:
            sent = None
        self._journal.append(("C", which, row, len(throttle), sent, t_ns))

    def events(self, events: list[dict], t_ns: int) -> None:
        self._journal.append(("E", pickle.dumps(events, pickle.HIGHEST_PROTOCOL) if events else None, t_ns))

    @property
    def message_count(self) -> int:
        """Messages in the bag (known once it is closed)."""
        return self._message_count

    def close(self) -> None:
        """Send what is journaled, wait until the writer has finished the bag (idempotent)."""
        if self._closed:
            if self._fault is None and self._flag[0]:  # failed after the last step's check
                self._writer_failed()
            if self._fault is not None:  # the writer has ended (it reported its fault, then returned)
                self._to_writer.close()
                self._from_writer.close()
            return
        self._closed = True
        try:
            if self._journal:
                self._send(("batch", self._slot, self._journal))
            self._send(("close",))
            self._expect("done")
        finally:
            self._proc.join(timeout=5)
            if self._proc.is_alive():
                self._proc.kill()
                self._proc.join()
            self._to_writer.close()
            self._from_writer.close()

    # ------------------------------------------------------------------ plumbing

    def _send_batch(self) -> None:
        # Ctrl-C is held back while a batch changes hands: an interrupt between sending it and
        # taking the next one would send it twice (the run finishes the bag after a Ctrl-C)
        held = _hold_sigint()
        try:
            self._send(("batch", self._slot, self._journal))
            self._journal = []
            self._rows = 0
            self._crows = [0, 0]
            while self._from_writer.poll():  # batches handed back meanwhile
                self._take(self._from_writer_recv())
            while not self._free:
                self._take(self._from_writer_recv())
            self._slot = self._free.pop(0)
        finally:
            _release_sigint(held)

    def _send(self, message: tuple) -> None:
        try:
            self._to_writer.send(message)
        except (BrokenPipeError, ConnectionResetError):
            self._died()

    def _from_writer_recv(self) -> tuple:
        try:
            return self._from_writer.recv()
        except EOFError:
            self._died()

    def _writer_failed(self):  # raises
        """The writer's error (it finished what it could of the bag first), the same each time."""
        if self._fault is None:
            self._expect("error")
        raise self._fault

    def _take(self, message: tuple) -> None:
        kind = message[0]
        if kind == "free":
            self._free.append(message[1])
        elif kind == "error":
            self._closed = True
            self._proc.join()
            self._fault = _error_of(message[1], self.bag_dir)
            raise self._fault
        elif kind == "done":
            self._message_count = message[1]
        elif kind != "ready":
            raise BagWriterError(f"bag {str(self.bag_dir)!r}: the writer process sent {kind!r}")

    def _expect(self, kind: str) -> None:
        """Take the writer's messages until one of ``kind`` (errors are raised)."""
        while True:
            message = self._from_writer_recv()
            self._take(message)
            if message[0] == kind:
                return

    def _died(self):  # raises
        if self._fault is not None:
            raise self._fault
        self._closed = True
        # a writer that failed said why before it ended: that error, not its end, is the news
        error = None
        try:
            while error is None and self._from_writer.poll():
                message = self._from_writer.recv()
                if message[0] == "error":
                    error = message[1]
        except (EOFError, OSError):
            pass
        self._proc.join(timeout=5)
        if error is not None:
            self._fault = _error_of(error, self.bag_dir)
            raise self._fault from None
        code = self._proc.exitcode
        raise BagWriterError(f"bag {str(self.bag_dir)!r}: the writer process ended unexpectedly "
                             f"(exit code {code}); the bag is incomplete") from None


_warmed = False


def _warm_up(recording: RecordingPlan, world) -> None:
    """Once per process: record one state inline into a scratch bag, so that what the recorder
    loads or compiles on first use (numba kernels from their cache, the typestore, YAML dumps)
    is in this process before it forks, instead of being loaded again by every writer process."""
    global _warmed
    if _warmed:
        return
    import tempfile

    with tempfile.TemporaryDirectory(prefix="evoscen-warm-") as tmp:
        rec = StepRecorder(Path(tmp) / "bag", recording, world.road)
        cols, t_ns = world.columns(), world.time_ns
        rec.world(world, cols, t_ns, roster=True)
        rec.state(world, cols, 0, 0, t_ns)
        if recording.bv_count:
            ids = world.ids[1:recording.bv_count + 1]
            rec.bv_commands(ids, np.zeros(len(ids)), np.zeros(len(ids), dtype=np.int64), t_ns)
        rec.events([], t_ns)
        rec.close()
    _warmed = True


def _hold_sigint():  # the mask before, or None
    """Block SIGINT in this thread (the main thread: where Python handles it); the mask before."""
    try:
        return signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    except (AttributeError, OSError, ValueError):
        return None


def _release_sigint(before) -> None:
    """Restore the mask :func:`_hold_sigint` found (a Ctrl-C that came meanwhile is raised now)."""
    if before is not None:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)


def _error_of(payload: tuple, bag_dir: Path) -> BaseException:
    """The writer's exception as it was raised there (or a one-line BagWriterError)."""
    pickled, text = payload
    if pickled is not None:
        try:
            return pickle.loads(pickled)
        except Exception:  # noqa: BLE001 - fall back to the text
            pass
    return BagWriterError(f"bag {str(bag_dir)!r}: the writer process failed: {text}")


def _writer_main(conn_in, conn_out, run_ends: tuple, bag_dir: Path, recording: RecordingPlan, road, f, i, c, topics,
                 flag) -> None:
    """The writer process: open the bag, replay batches until ``close`` (or the run's end), close."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the run's to handle (module docstring)
    for end in run_ends:  # the fork copied the run's ends of the pipes: without closing them here,
        end.close()       # the run's end would never read as closed (EOF) in this process
    def tell(message: tuple) -> bool:
        """Send ``message`` to the run; False if the run is gone (its end of the pipe closed)."""
        try:
            conn_out.send(message)
        except OSError:
            return False
        return True

    rec = None
    try:
        rec = StepRecorder(bag_dir, recording, road)
        tell(("ready",))
        ids = [None, None]
        while True:
            try:
                message = conn_in.recv()
            except (EOFError, OSError):  # the run went away: finish the bag with what came
                break
            if message[0] == "close":
                break
            _, slot, journal = message
            _replay(rec, road, journal, f[slot], i[slot], (c[0][slot], c[1][slot]), topics, ids)
            if not tell(("free", slot)):  # the run went away while this batch was replayed
                break
        rec.close()
        tell(("done", rec.message_count))
    except BaseException as exc:  # noqa: BLE001 - reported to the run, which raises it
        if isinstance(exc, HostFault):
            flag[0] = 1  # the run stops at its next step boundary and waits for the error
            if rec is not None:
                try:  # the bag finished from what reached the disk, or cut back for the reindexer
                    rec.close()
                except BaseException:  # noqa: BLE001 - the same fault again
                    pass
        try:
            pickled = pickle.dumps(exc)
        except Exception:  # noqa: BLE001
            pickled = None
        tell(("error", (pickled, f"{type(exc).__name__}: {exc}")))


def _replay(rec, road, journal: list, f: np.ndarray, i: np.ndarray, c: tuple, topics: tuple,
            ids: list) -> None:
    """Make the calls of a journal on the inline recorder (same order, same data)."""
    cols = None
    for entry in journal:
        kind = entry[0]
        if kind == "W":
            _, row, t_ns, roster = entry
            fr, ir = f[row], i[row]
            cols = state_columns(road, (tuple(fr), tuple(ir)))
            rec.world(None, cols, t_ns, roster=roster)
        elif kind == "S":
            _, row, sut_index, step_index, t_ns = entry
            rec.state(None, cols, sut_index, step_index, t_ns)
        elif kind == "C":
            _, which, row, n, sent, t_ns = entry
            if sent is not None:
                ids[which] = sent
            table = c[which][row]
            if topics[which] == rec.T.COMMANDS_BV.name:  # all BVs: split by BV node
                rec.bv_commands(ids[which], table[0, :n], table[1, :n], t_ns)
            else:
                rec.commands(topics[which], ids[which], table[0, :n], table[1, :n], t_ns)
        else:
            _, pickled, t_ns = entry
            rec.events(pickle.loads(pickled) if pickled is not None else [], t_ns)
