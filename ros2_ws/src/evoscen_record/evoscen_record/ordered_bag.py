"""The canonical message order of a bag: :class:`OrderedBag`, the ordering buffer in front of a
:class:`~evoscen_record.recorder.BagRecorder` that both runners write through."""

from __future__ import annotations

import bisect
from collections.abc import Callable, Collection, Sequence

from evoscen_contract.topics import TopicSpec
from evoscen_record.recorder import BagRecorder


class OrderedBag:
    """A :class:`BagRecorder` front that writes messages in one canonical order.

    Messages are written sorted by (log time, the topic's rank in ``topics``, arrival order
    within the topic). The in-process runner produces messages in some order, the node graph
    receives them from several publishers in whatever order the middleware delivers; both
    write through this class, so the bag's bytes depend only on the messages.

    A message is held until :meth:`flush_before` passes its time (the graph's evaluator
    calls it with the oldest of the per-step topics' latest stamps, the in-process runner
    with the current step) and at :meth:`close`. A message arriving for a time already
    flushed is written at once and counted in ``late_messages`` (the order is then no longer
    canonical; with one message per step on every per-step topic it cannot happen).
    """

    def __init__(self, bag: BagRecorder, topics: Sequence[TopicSpec]) -> None:
        self.bag = bag
        self._rank = {spec.name: k for k, spec in enumerate(topics)}
        self._pending: list[tuple[int, int, int, str, bytes, bool]] = []
        self._seq = 0
        self._flushed_before = -1
        self.late_messages = 0
        self.on_write: Callable[[str, bytes], None] | None = None
        """Called with ``(topic, data)`` for every message, in the order written (the live scores)."""

    def add(self, topic: str, data: bytes, log_time_ns: int, *, canonical: bool = False) -> None:
        """Queue one serialized message (see :meth:`BagRecorder.write`)."""
        if log_time_ns < self._flushed_before:
            self.late_messages += 1
            self.bag.write(topic, data, log_time_ns, canonical=canonical)
            if self.on_write is not None:
                self.on_write(topic, data)
            return
        self._seq += 1
        self._pending.append((log_time_ns, self._rank[topic], self._seq, topic, data, canonical))

    def drop_pending(self, topics: Collection[str], from_ns: int) -> int:
        """Forget the queued messages of ``topics`` with a log time at or after ``from_ns`` (not yet
        written); returns how many. The evaluator drops the controllers' answers to the step a run
        ended at (docs/recording.md, "A controller that dies during a step")."""
        keep = [m for m in self._pending if not (m[3] in topics and m[0] >= from_ns)]
        dropped = len(self._pending) - len(keep)
        self._pending = keep
        return dropped

    def flush_before(self, time_ns: int) -> None:
        """Write every queued message with a log time before ``time_ns``, in canonical order."""
        if not self._pending:
            self._flushed_before = max(self._flushed_before, time_ns)
            return
        pending = self._pending
        pending.sort()  # (time, rank, arrival): unique keys
        if pending[-1][0] < time_ns:  # the usual case: all of them
            ready, self._pending = pending, []
        else:
            k = bisect.bisect_left(pending, (time_ns,))  # the first at time_ns or later
            ready, self._pending = pending[:k], pending[k:]
        if ready:
            if self.on_write is None:
                if self.bag._chunk is not None:  # the recorder's own queue format
                    self.bag._write_queued(ready)
                else:
                    self.bag.write_many([(t, topic, data, canonical) for t, _, _, topic, data, canonical in ready])
            else:
                for t, _, _, topic, data, canonical in ready:
                    self.bag.write(topic, data, t, canonical=canonical)
                    self.on_write(topic, data)
        self._flushed_before = max(self._flushed_before, time_ns)

    def close(self) -> None:
        """Write everything still queued and close the bag (idempotent)."""
        if not self.bag.closed:
            try:
                self.flush_before(2**63 - 1)
            finally:  # after a fault of the host too: the bag is finished from what reached the disk
                self.bag.close()

    @property
    def message_count(self) -> int:
        """Messages written so far."""
        return self.bag.message_count
