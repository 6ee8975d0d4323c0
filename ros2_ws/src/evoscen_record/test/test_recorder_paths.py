"""The recorder's three write paths give the same bytes (issue 14).

:class:`~evoscen_record.recorder.BagRecorder` writes messages through the mcap library's
``Writer.add_message`` (``fast_writes=False``), through :class:`~evoscen_record.mcap_internals.FastMessages`
(one ``pack`` per record into the library's chunk builder; ``chunk_writes=False``) or through
:class:`~evoscen_record.mcap_internals.ChunkMessages` (the recorder keeps the open chunk and writes chunk
record and message indexes itself; the default). The same messages — random topics, sizes 0 to
3,000 bytes, equal and decreasing log times — written every way, with chunks closed by size, by
the 1-s rule and by explicit flushes, must give byte-identical files for every compression; so
must an empty bag.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from evoscen_contract.topics import CONTRACT
from evoscen_record import mcap_internals as MI
from evoscen_record import metadata_yaml
from evoscen_record.bag_reader import open_bag_reader
from evoscen_record.recorder import BagRecorder

PATHS = {"library": {"fast_writes": False}, "fast": {"chunk_writes": False}, "chunk": {}}


def _plan(seed: int, n: int) -> list[tuple[str, bytes, int]]:
    rng = np.random.default_rng(seed)
    topics = [spec.name for spec in CONTRACT]
    return [(topics[int(rng.integers(0, len(topics)))],
             bytes(rng.integers(0, 256, int(rng.integers(0, 3000)), dtype=np.uint8)),
             int(k // 3) * 50_000_000 + int(rng.integers(0, 2)) * 7) for k in range(n)]


def _record(path: Path, plan, *, flush_every: int = 0, **kwargs) -> bytes:
    bag = BagRecorder(path / "bag", CONTRACT, **kwargs)
    for k, (topic, data, t) in enumerate(plan):
        bag.write(topic, data, t, canonical=True)
        if flush_every and k % flush_every == flush_every - 1:
            bag.flush()
    bag.close()
    return (path / "bag" / "bag_0.mcap").read_bytes()


@pytest.mark.parametrize("compression", ["none", "zstd", "lz4"])
@pytest.mark.parametrize("chunk_size", [4096, 1024 * 1024])
def test_write_paths_give_the_same_bytes(tmp_path: Path, compression: str, chunk_size: int) -> None:
    plan = _plan(7, 500)
    files = {name: _record(tmp_path / name, plan, compression=compression, chunk_size=chunk_size, **kw)
             for name, kw in PATHS.items()}
    assert files["chunk"] == files["library"]
    assert files["fast"] == files["library"]
    # and the bag reads back as written
    back = [(topic, t, data) for topic, _, t, data in open_bag_reader(tmp_path / "chunk" / "bag")]
    assert back == [(topic, t, data) for topic, data, t in plan]


def test_write_paths_with_flushes_and_no_time_bound(tmp_path: Path) -> None:
    plan = _plan(8, 300)
    for kwargs in ({"flush_every": 17}, {"chunk_duration_ns": 0, "chunk_size": 2000}, {"chunk_duration_ns": 0}):
        files = {name: _record(tmp_path / f"{name}{len(kwargs)}{sorted(kwargs)}", plan, **kwargs, **kw)
                 for name, kw in PATHS.items()}
        assert len(set(files.values())) == 1, kwargs


def test_empty_bag_is_the_same_every_way(tmp_path: Path) -> None:
    files = {name: _record(tmp_path / name, [], **kw) for name, kw in PATHS.items()}
    assert len(set(files.values())) == 1


def test_chunk_path_is_used_and_falls_back(tmp_path: Path, monkeypatch) -> None:
    assert BagRecorder(tmp_path / "a" / "bag", CONTRACT)._chunk is not None
    assert BagRecorder(tmp_path / "b" / "bag", CONTRACT, chunk_writes=False)._chunk is None
    monkeypatch.setattr(MI.ChunkMessages, "usable", staticmethod(lambda writer: False))  # another mcap
    assert BagRecorder(tmp_path / "c" / "bag", CONTRACT)._chunk is None


def test_metadata_yaml_from_one_dump_equals_the_two_dumps(tmp_path: Path) -> None:
    """``dump_metadata_yaml`` (one libyaml dump, the nested document indented) gives the texts of
    the two Python-emitter dumps: for a recorded bag's metadata, an empty bag's, and made-up ones
    whose strings look like other YAML types or are empty, long or odd (those fall back)."""
    import copy

    import yaml

    bag = BagRecorder(tmp_path / "b" / "bag", CONTRACT)
    for topic, data, t in _plan(3, 50):
        bag.write(topic, data, t, canonical=True)
    bag.close()
    empty = BagRecorder(tmp_path / "e" / "bag", CONTRACT)
    empty.close()
    infos = [bag.metadata()["rosbag2_bagfile_information"], empty.metadata()["rosbag2_bagfile_information"]]
    odd = ["true", "1.5", "", "null", "~", "-", "0x10", "1e3", "yes", "on", "a.b/c-d_e", "007", "x" * 100,
           "x" * 101, "has space", "colon:", "quote'", "ümlaut", "new\nline", "#hash", "[flow]", "- item"]
    for value in odd:
        info = copy.deepcopy(infos[0])
        info["files"][0]["path"] = value
        info["topics_with_message_count"][1]["topic_metadata"]["name"] = value
        info["custom_data"] = {value: value} if value else {}
        infos.append(info)
    assert any(metadata_yaml._plain_strings(i) for i in infos[2:]) and not all(metadata_yaml._plain_strings(i) for i in infos[2:])
    for info in infos:
        expected = (yaml.safe_dump(info, sort_keys=False, default_flow_style=False),
                    yaml.safe_dump({"rosbag2_bagfile_information": info}, sort_keys=False, default_flow_style=False))
        assert metadata_yaml.dump_metadata_yaml(info) == expected, info


@pytest.mark.parametrize("kwargs", [{}, {"chunk_size": 4096}, {"chunk_duration_ns": 0, "chunk_size": 2000},
                                    {"compression": "none"}, {"chunk_writes": False}, {"fast_writes": False}])
def test_batched_writes_equal_one_write_per_message(tmp_path: Path, kwargs) -> None:
    """``write_many`` and :class:`~evoscen_record.ordered_bag.OrderedBag` (on the chunk path: one loop,
    ``BagRecorder._write_queued``) give the file of one :meth:`write` per message in the same order:
    batches of 1 to 40 messages, chunks closed by size and by the 1-s rule inside a batch, data
    given as ``bytes``, ``bytearray`` or ``memoryview``, times as ``int`` or numpy integers."""
    from evoscen_record.ordered_bag import OrderedBag

    plan = _plan(9, 600)
    rng = np.random.default_rng(4)
    kinds = rng.integers(0, 3, len(plan))
    as_given = [(topic, (bytes, bytearray, memoryview)[int(k)](data), np.int64(t) if k == 1 else t)
                for (topic, data, t), k in zip(plan, kinds)]
    one = _record(tmp_path / "one", plan, **kwargs)
    bag = BagRecorder(tmp_path / "many" / "bag", CONTRACT, **kwargs)
    k = 0
    while k < len(as_given):
        n = int(rng.integers(1, 41))
        bag.write_many([(t, topic, data, True) for topic, data, t in as_given[k:k + n]])
        k += n
    bag.close()
    assert (tmp_path / "many" / "bag" / "bag_0.mcap").read_bytes() == one
    # OrderedBag sorts by (time, topic rank, arrival): give it the plan in that order already, per time
    rank = {spec.name: r for r, spec in enumerate(CONTRACT)}
    ordered_plan = sorted(plan, key=lambda m: m[2])  # stable: arrival order within a time
    ordered_plan = sorted(ordered_plan, key=lambda m: (m[2], rank[m[0]]))
    expected = _record(tmp_path / "sorted", ordered_plan, **kwargs)
    ob = OrderedBag(BagRecorder(tmp_path / "ordered" / "bag", CONTRACT, **kwargs), CONTRACT)
    for j, (topic, data, t) in enumerate(plan):
        if j % 7 == 0:
            ob.flush_before(t - 7)  # the queue's earlier times go out (no later message is earlier)
        ob.add(topic, data, t, canonical=True)
    ob.close()
    assert ob.late_messages == 0
    assert (tmp_path / "ordered" / "bag" / "bag_0.mcap").read_bytes() == expected


def test_batched_writes_check_as_write_does(tmp_path: Path) -> None:
    """A bad message in a batch raises what :meth:`write` raises, after the ones before it."""
    bag = BagRecorder(tmp_path / "b" / "bag", CONTRACT)
    with pytest.raises(ValueError, match="not declared"):
        bag.write_many([(5, "/clock", b"\x00\x01\x00\x00" + bytes(8), True), (6, "/nope", b"", True)])
    with pytest.raises(ValueError, match=">= 0"):
        bag.write_many([(-1, "/clock", b"", True)])
    assert bag.message_count == 1
    bag.close()
    with pytest.raises(ValueError, match="after close"):
        bag.write_many([(7, "/clock", b"", True)])


@pytest.mark.parametrize("kwargs", [{}, {"chunk_size": 4096}, {"chunk_duration_ns": 0, "chunk_size": 2000},
                                    {"compression": "lz4"}, {"chunk_writes": False}, {"fast_writes": False}])
def test_write_parts_equals_write_many(tmp_path: Path, kwargs) -> None:
    """``write_parts`` (one time, messages as pieces of their bytes) gives the file of ``write_many``
    of the joined messages: steps of 1 to 12 messages cut into 1 to 5 pieces (empty ones too),
    chunks closed by size inside a step and by the 1-s rule between steps, an unknown topic (the
    checked path) and an empty step."""
    plan = _plan(12, 700)
    rng = np.random.default_rng(6)
    steps, k = [], 0
    while k < len(plan):
        n = int(rng.integers(1, 13))
        t = 10_000 + 97_000_000 * len(steps)
        steps.append((t, [(topic, data) for topic, data, _ in plan[k:k + n]]))
        k += n
    steps.insert(3, (steps[2][0], []))

    def pieces(data: bytes) -> tuple[bytes, ...]:
        cuts = sorted(int(c) for c in rng.integers(0, len(data) + 1, int(rng.integers(0, 5))))
        return tuple(data[a:b] for a, b in zip([0, *cuts], [*cuts, len(data)]))

    many = BagRecorder(tmp_path / "many" / "bag", CONTRACT, **kwargs)
    parts = BagRecorder(tmp_path / "parts" / "bag", CONTRACT, **kwargs)
    for t, messages in steps:
        many.write_many([(t, topic, data, True) for topic, data in messages])
        parts.write_parts(t, [(topic, pieces(data)) for topic, data in messages])
    many.close()
    parts.close()
    assert (tmp_path / "parts" / "bag" / "bag_0.mcap").read_bytes() == \
        (tmp_path / "many" / "bag" / "bag_0.mcap").read_bytes()
    assert parts.topic_message_counts() == many.topic_message_counts()
    bag = BagRecorder(tmp_path / "bad" / "bag", CONTRACT, **kwargs)
    with pytest.raises(ValueError, match="not declared"):
        bag.write_parts(5, [("/clock", (b"\x00\x01\x00\x00", bytes(8))), ("/nope", (b"",))])
    assert bag.message_count == 1
    bag.close()


def test_ordered_bag_drops_the_answers_to_the_step_a_run_ended_at(tmp_path: Path) -> None:
    """``OrderedBag.drop_pending`` forgets exactly the queued messages of the named topics at or after
    the time given (the evaluator's rule for a run that ends at step K: no answer to K is recorded),
    whatever their arrival order; messages of other topics at K and every message before K stay."""
    from evoscen_record.ordered_bag import OrderedBag

    sut, clock, world = "/evoscen/commands/sut", "/clock", "/evoscen/world"
    k_ns = 300_000_000  # the step the run ended at (step 3 of 0.1 s)
    ob = OrderedBag(BagRecorder(tmp_path / "b" / "bag", CONTRACT), CONTRACT)
    # steps 0..2 answered and flushed as the evaluator does; then the answer to 3 arrives before the end
    for step in range(3):
        t = step * 100_000_000
        ob.add(world, bytes([step]), t, canonical=True)
        ob.add(sut, bytes([10 + step]), t, canonical=True)
    ob.flush_before(200_000_000)  # steps 0, 1 written; 2 still queued
    ob.add(sut, b"\x13", k_ns, canonical=True)  # the answer to K, arrived first
    ob.add(world, b"\x03", k_ns, canonical=True)
    ob.add(clock, b"\x00\x01\x00\x00" + bytes(8), k_ns, canonical=True)
    assert ob.drop_pending({sut}, k_ns) == 1  # only the answer to K, not the answer to 2 nor the state at K
    assert ob.drop_pending({sut}, k_ns) == 0
    ob.close()
    got = [(topic, t, data) for topic, _, t, data in open_bag_reader(tmp_path / "b" / "bag")]
    assert [(t, n) for t, n, _ in got if t == sut] == [(sut, 0), (sut, 100_000_000), (sut, 200_000_000)]
    assert [(t, n) for t, n, _ in got if t == world] == [(world, 0), (world, 100_000_000), (world, 200_000_000),
                                                         (world, k_ns)]
    assert [(t, n) for t, n, _ in got if t == clock] == [(clock, k_ns)]
