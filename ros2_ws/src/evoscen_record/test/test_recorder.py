"""Tests of evoscen_record.recorder: a rosbag2 MCAP bag readable by rosbags and mcap_ros2.

A fake 100-step run (dt = 0.1 s, 3 vehicles) is recorded: /evoscen/roster once, then
per step /clock, /evoscen/world, both command tables and the SUT odometry, and
/evoscen/events every 10th step. Expected values are the formulas that made them.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml
from evoscen_contract.tables import table_array, table_columns, table_message
from evoscen_contract.topics import (
    COMMAND_FIELDS,
    CONTRACT,
    POLICY_CODES,
    ROSTER_FIELDS,
    WORLD_FIELDS,
    clock_message,
    events_message,
    odometry_message,
    parse_events,
)
from evoscen_record.bag_reader import open_bag_reader
from evoscen_record.recorder import BagRecorder
from evoscen_record.schemas import message_definition
from evoscen_sim.errors import InputError
from mcap.reader import make_reader
from rclpy.serialization import serialize_message

STEPS = 100
DT_NS = 100_000_000  # 0.1 s
IDS = np.array([0.0, 1.0, 2.0])  # id 0 = SUT, 1..2 BVs
N_EVENTS = STEPS // 10
#: roster + 5 per step + events every 10th step
N_MESSAGES = 1 + 5 * STEPS + N_EVENTS


def world_rows(k: int) -> np.ndarray:
    """World table of step k: x = 10*id + 3*k*dt... (simple closed forms)."""
    t = k * 0.1
    rows = np.zeros((len(IDS), len(WORLD_FIELDS)))
    col = {name: i for i, name in enumerate(WORLD_FIELDS)}
    rows[:, col["id"]] = IDS
    rows[:, col["role"]] = [1, 0, 0]
    rows[:, col["policy"]] = [POLICY_CODES["sut"], POLICY_CODES["competitive"],
                              POLICY_CODES["mutual"]]
    rows[:, col["x"]] = 10.0 * IDS + 30.0 * t
    rows[:, col["y"]] = -3.5 * IDS
    rows[:, col["speed"]] = 30.0 + IDS + 0.01 * k
    rows[:, col["lane"]] = [1, 2, 3]
    rows[:, col["length"]] = 4.5
    rows[:, col["width"]] = 1.8
    return rows


def command_rows(ids: np.ndarray, k: int) -> np.ndarray:
    """Command table: throttle = 0.01*k - 0.5, lane_change = +1 on step 50 only."""
    out = np.zeros((len(ids), len(COMMAND_FIELDS)))
    out[:, 0] = ids
    out[:, 1] = 0.01 * k - 0.5
    out[:, 2] = 1.0 if k == 50 else 0.0
    return out


def step_events(k: int) -> list[dict]:
    """Events of step k (every 10th step one lane change)."""
    if k % 10:
        return []
    return [{"name": "evoscen/lane_change", "level": 0, "message": "", "step": k,
             "time_s": k * 0.1, "ids": [1], "direction": 1, "duration_s": 2.5}]


def record(bag_dir: Path, **kwargs) -> Path:
    """Record the fake run into bag_dir (raw CDR writes and write_message mixed)."""
    with BagRecorder(bag_dir, CONTRACT, **kwargs) as bag:
        roster = np.column_stack([IDS, [1, 0, 0], [4, 2, 1], [4.5] * 3, [1.8] * 3])
        bag.write("/evoscen/roster", serialize_message(
            table_message(ROSTER_FIELDS, roster, 0, "map")), 0)
        for k in range(STEPS):
            t = k * DT_NS
            bag.write_message("/clock", clock_message(t), t)
            bag.write("/evoscen/world",
                      serialize_message(table_message(WORLD_FIELDS, world_rows(k), t, "map")), t)
            bag.write("/evoscen/commands/bv", serialize_message(
                table_message(COMMAND_FIELDS, command_rows(IDS[1:], k), t, "map")), t)
            bag.write_message("/evoscen/commands/sut",
                              table_message(COMMAND_FIELDS, command_rows(IDS[:1], k), t, "map"), t)
            bag.write_message("/evoscen/sut/odom",
                              odometry_message(30.0 * k * 0.1, 0.0, 0.0, 30.0, 0.0, t), t)
            if step_events(k):
                bag.write_message("/evoscen/events", events_message(step_events(k), t), t)
    return bag_dir


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One recorded bag shared by the read-back tests."""
    return record(tmp_path_factory.mktemp("rec") / "run1")


def test_layout(bag: Path) -> None:
    assert sorted(p.name for p in bag.iterdir()) == ["metadata.yaml", "run1_0.mcap"]


def test_read_back_with_rosbags(bag: Path) -> None:
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    counts: dict[str, int] = {}
    with Reader(bag) as reader:
        assert reader.message_count == N_MESSAGES
        conns = {c.topic: c for c in reader.connections}
        assert conns["/evoscen/roster"].ext.offered_qos_profiles[0].durability.name == \
            "TRANSIENT_LOCAL"
        assert conns["/evoscen/world"].msgtype == "sensor_msgs/msg/PointCloud2"
        assert conns["/evoscen/world"].digest == store.hash_rihs01("sensor_msgs/msg/PointCloud2")
        for conn, t, raw in reader.messages():
            msg = store.deserialize_cdr(raw, conn.msgtype)
            counts[conn.topic] = counts.get(conn.topic, 0) + 1
            if conn.topic == "/evoscen/world":
                k = t // DT_NS
                assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == t
                assert [f.name for f in msg.fields] == list(WORLD_FIELDS)
                np.testing.assert_array_equal(table_array(msg), world_rows(k))
            elif conn.topic == "/evoscen/commands/bv":
                np.testing.assert_array_equal(table_array(msg), command_rows(IDS[1:], t // DT_NS))
            elif conn.topic == "/clock":
                assert msg.clock.sec * 10**9 + msg.clock.nanosec == t
            elif conn.topic == "/evoscen/sut/odom":
                assert msg.child_frame_id == "sut/base_link"
                assert msg.pose.pose.position.x == 30.0 * (t // DT_NS) * 0.1
            elif conn.topic == "/evoscen/events":
                assert parse_events(msg) == step_events(t // DT_NS)
            elif conn.topic == "/evoscen/roster":
                assert table_columns(msg)["policy"].tolist() == [4.0, 2.0, 1.0]
    assert counts == {"/evoscen/roster": 1, "/clock": STEPS, "/evoscen/world": STEPS,
                      "/evoscen/commands/bv": STEPS, "/evoscen/commands/sut": STEPS,
                      "/evoscen/sut/odom": STEPS, "/evoscen/events": N_EVENTS}


def test_read_back_with_mcap_ros2(bag: Path) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        from mcap_ros2.reader import read_ros2_messages

    n = 0
    for m in read_ros2_messages(str(bag / "run1_0.mcap")):
        n += 1
        t = m.log_time_ns
        if m.channel.topic == "/evoscen/world":
            np.testing.assert_array_equal(table_array(m.ros_msg), world_rows(t // DT_NS))
        elif m.channel.topic == "/evoscen/commands/sut":
            np.testing.assert_array_equal(table_array(m.ros_msg),
                                          command_rows(IDS[:1], t // DT_NS))
        elif m.channel.topic == "/evoscen/events":
            assert parse_events(m.ros_msg) == step_events(t // DT_NS)
        elif m.channel.topic == "/evoscen/sut/odom":
            assert m.ros_msg.twist.twist.linear.x == 30.0
        elif m.channel.topic == "/clock":
            assert m.ros_msg.clock.sec * 10**9 + m.ros_msg.clock.nanosec == t
    assert n == N_MESSAGES


def test_mcap_summary_schemas_and_channels(bag: Path) -> None:
    with open(bag / "run1_0.mcap", "rb") as f:
        reader = make_reader(f)
        header = reader.get_header()
        assert header.profile == "ros2"
        summary = reader.get_summary()
        assert summary is not None
        stats = summary.statistics
        assert stats.message_count == N_MESSAGES
        assert stats.channel_count == len(CONTRACT)
        # Clock, PointCloud2 (4 topics), Odometry, DiagnosticArray, MarkerArray (2 topics)
        assert stats.schema_count == 5
        assert stats.message_start_time == 0
        assert stats.message_end_time == (STEPS - 1) * DT_NS
        assert summary.chunk_indexes and all(ci.compression == "zstd"
                                             for ci in summary.chunk_indexes)
        assert all(ci.message_index_offsets for ci in summary.chunk_indexes)
        for schema in summary.schemas.values():
            assert schema.encoding == "ros2msg"
            assert schema.data.decode() == message_definition(schema.name)
        by_topic = {c.topic: c for c in summary.channels.values()}
        for channel in by_topic.values():
            assert channel.message_encoding == "cdr"
            assert channel.metadata["topic_type_hash"].startswith("RIHS01_")
        qos = yaml.safe_load(by_topic["/clock"].metadata["offered_qos_profiles"])
        assert qos[0]["reliability"] == "reliable" and qos[0]["history"] == "keep_all" and qos[0]["depth"] == 0
        assert stats.channel_message_counts[by_topic["/evoscen/events"].id] == N_EVENTS
        (meta,) = list(reader.iter_metadata())
        assert meta.name == "rosbag2"
        assert yaml.safe_load(meta.metadata["serialized_metadata"])["message_count"] == N_MESSAGES


def test_schema_text_is_rosbag2_concatenation() -> None:
    text = message_definition("sensor_msgs/msg/PointCloud2")
    sep = "\n" + "=" * 80 + "\nMSG: "
    parts = text.split(sep)
    assert [p.splitlines()[0] for p in parts[1:]] == [
        "sensor_msgs/PointField", "std_msgs/Header", "builtin_interfaces/Time"]
    assert "PointField[] fields" in parts[0]


def test_metadata_yaml(bag: Path) -> None:
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == 9 and info["storage_identifier"] == "mcap"
    assert info["ros_distro"] == "jazzy" and info["custom_data"] == {}
    assert info["message_count"] == N_MESSAGES
    assert info["starting_time"] == {"nanoseconds_since_epoch": 0}
    assert info["duration"] == {"nanoseconds": (STEPS - 1) * DT_NS}
    assert info["relative_file_paths"] == ["run1_0.mcap"]
    assert info["files"][0]["path"] == "run1_0.mcap"
    assert info["files"][0]["message_count"] == N_MESSAGES
    assert info["compression_format"] == "" and info["compression_mode"] == ""
    counts = {t["topic_metadata"]["name"]: t["message_count"]
              for t in info["topics_with_message_count"]}
    assert counts == {"/clock": STEPS, "/evoscen/world": STEPS, "/evoscen/commands/bv": STEPS,
                      "/evoscen/commands/sut": STEPS, "/evoscen/sut/odom": STEPS,
                      "/evoscen/events": N_EVENTS, "/evoscen/roster": 1,
                      "/evoscen/markers": 0, "/evoscen/map_markers": 0}  # declared, none written here
    world = info["topics_with_message_count"][1]["topic_metadata"]
    assert world["type"] == "sensor_msgs/msg/PointCloud2"
    assert world["serialization_format"] == "cdr"
    assert world["offered_qos_profiles"][0]["history"] == "keep_all"
    assert world["type_description_hash"].startswith("RIHS01_")


def test_open_bag_reader(bag: Path) -> None:
    items = list(open_bag_reader(bag))
    assert len(items) == N_MESSAGES
    topic, type_name, t, data = items[0]
    assert (topic, type_name, t) == ("/evoscen/roster", "sensor_msgs/msg/PointCloud2", 0)
    assert isinstance(data, bytes)
    times = [t for _, _, t, _ in open_bag_reader(bag, log_time_order=True)]
    assert times == sorted(times)


def test_byte_identical_rerun(bag: Path, tmp_path: Path) -> None:
    again = record(tmp_path / "run1")
    assert (again / "run1_0.mcap").read_bytes() == (bag / "run1_0.mcap").read_bytes()
    assert (again / "metadata.yaml").read_bytes() == (bag / "metadata.yaml").read_bytes()


def test_small_chunks_and_lz4_hold_the_same_messages(bag: Path, tmp_path: Path) -> None:
    other = record(tmp_path / "small", chunk_size=16 * 1024, compression="lz4")
    with open(other / "small_0.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and len(summary.chunk_indexes) > 10
    assert {ci.compression for ci in summary.chunk_indexes} == {"lz4"}
    assert list(open_bag_reader(other)) == list(open_bag_reader(bag))


def test_serialize_message_padding_is_not_reproducible_but_recorded_bytes_are(
    tmp_path: Path,
) -> None:
    """Why the recorder canonicalizes: rclpy leaves CDR padding uninitialized."""
    from diagnostic_msgs.msg import DiagnosticArray
    from evoscen_record.canonical_cdr import CanonicalCdr
    from rclpy.serialization import deserialize_message

    msg = events_message(step_events(0) + [{"name": "evoscen/fault", "controller": "x"}], 0)
    canon = CanonicalCdr(["diagnostic_msgs/msg/DiagnosticArray"])
    outs = set()
    for _ in range(20):
        raw = serialize_message(msg)
        fixed = canon("diagnostic_msgs/msg/DiagnosticArray", raw)
        # canonical = zeroed padding, total length padded with zeros to 4 bytes (as DDS sends it)
        assert len(fixed) == len(raw) + (-len(raw) % 4) and len(fixed) % 4 == 0
        assert fixed[len(raw):] == bytes(len(fixed) - len(raw))
        assert parse_events(deserialize_message(fixed, DiagnosticArray)) == parse_events(msg)
        # only padding may differ, and canonical padding is zero
        assert all(b == 0 for a, b in zip(raw, fixed) if a != b)
        outs.add(fixed)
    assert len(outs) == 1
    with pytest.raises(ValueError, match="does not decode"):
        canon("diagnostic_msgs/msg/DiagnosticArray", b"\x00\x01\x00\x00\xff")


def test_close_is_idempotent_and_write_after_close_fails(tmp_path: Path) -> None:
    rec = BagRecorder(tmp_path / "b", CONTRACT[:1], compression="none")
    rec.write_message("/clock", clock_message(5), 5)
    rec.close()
    rec.close()
    assert rec.closed
    with pytest.raises(ValueError, match="after close"):
        rec.write("/clock", b"", 6)
    assert [x[2] for x in open_bag_reader(tmp_path / "b")] == [5]


def test_write_errors(tmp_path: Path) -> None:
    with BagRecorder(tmp_path / "b", CONTRACT) as rec:
        with pytest.raises(ValueError, match="not declared"):
            rec.write("/nope", b"", 0)
        with pytest.raises(ValueError, match="carries rosgraph_msgs/msg/Clock"):
            rec.write_message("/clock", odometry_message(0, 0, 0, 0, 0, 0), 0)
        with pytest.raises(ValueError, match="does not decode"):
            rec.write("/clock", b"\x00\x01\x00\x00", 0)
        with pytest.raises(ValueError, match=">= 0"):
            rec.write("/clock", serialize_message(clock_message(0)), -1)


def test_existing_non_empty_dir_is_input_error(tmp_path: Path) -> None:
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x.txt").write_text("x")
    with pytest.raises(InputError, match=str(tmp_path / "full")):
        BagRecorder(tmp_path / "full", CONTRACT)
    (tmp_path / "empty").mkdir()
    BagRecorder(tmp_path / "empty", CONTRACT).close()  # an empty directory is fine


def test_uncreatable_dir_is_input_error(tmp_path: Path) -> None:
    # Tests run as root, so chmod cannot make a directory unwritable: put it under a file.
    (tmp_path / "afile").write_text("not a directory")
    target = tmp_path / "afile" / "bag"
    with pytest.raises(InputError, match=str(target)):
        BagRecorder(target, CONTRACT)


def test_bad_arguments(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="compression"):
        BagRecorder(tmp_path / "b", CONTRACT, compression="bz2")
    with pytest.raises(InputError, match="duplicate"):
        BagRecorder(tmp_path / "b", CONTRACT + CONTRACT[:1])
    assert not (tmp_path / "b").exists()


def test_reader_errors_name_the_path(tmp_path: Path) -> None:
    missing = tmp_path / "missing"
    with pytest.raises(InputError, match=str(missing)):
        open_bag_reader(missing)
    corrupt = tmp_path / "corrupt"
    corrupt.mkdir()
    (corrupt / "corrupt_0.mcap").write_bytes(b"this is not an mcap file at all" * 10)
    with pytest.raises(InputError, match=str(corrupt)):
        list(open_bag_reader(corrupt))


def test_truncated_bag_is_input_error(bag: Path, tmp_path: Path) -> None:
    trunc = tmp_path / "trunc"
    trunc.mkdir()
    data = (bag / "run1_0.mcap").read_bytes()
    (trunc / "trunc_0.mcap").write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match=str(trunc)):
        list(open_bag_reader(trunc))


def test_external_sut_is_recorded_in_the_metadata_and_named_by_the_report(tmp_path: Path) -> None:
    from evoscen_eval.scoring.metrics import run_info
    from evoscen_eval.scoring.rundata import read_run
    from evoscen_record.scenario_record import SCENARIO_METADATA, scenario_metadata
    from evoscen_sim.config.scenario_config import load_scenario_config

    cfg = load_scenario_config(None)
    plain = scenario_metadata(cfg)
    external = scenario_metadata(cfg, external_sut=True)
    assert set(plain) == {"scenario_yaml", "map_sha256"}  # own SUT: the configuration and the map's hash only
    assert external == {**plain, "sut_source": "external"}

    run = read_run(record(tmp_path / "own", metadata={SCENARIO_METADATA: plain}))
    assert run.external_sut is False and run_info(run)["sut_model"] == cfg.sut.model
    run = read_run(record(tmp_path / "ext", metadata={SCENARIO_METADATA: external}))
    assert run.external_sut is True and run_info(run)["sut_model"] == "external"

    bad = record(tmp_path / "bad", metadata={SCENARIO_METADATA: {**plain, "sut_source": "remote"}})
    with pytest.raises(InputError) as info:
        read_run(bad)
    assert str(info.value) == (f"bag {str(bad / 'bad_0.mcap')!r}: metadata record 'evoscen': key 'sut_source' = "
                               "'remote': expected 'external' (or no such key)")


@pytest.mark.parametrize("compression", ["none", "zstd"])
def test_fast_message_path_writes_the_librarys_bytes(tmp_path: Path, monkeypatch, compression: str) -> None:
    """The recorder's one-pack message and message-index writing (:class:`evoscen_record.mcap_internals.FastMessages`) gives the
    bytes of mcap's own ``Writer.add_message``: the same messages — several topics, sizes from
    0 to 3,000 bytes, equal and decreasing log times, chunks closed by size (4 kB) and by the
    1-s duration rule — recorded both ways, byte for byte."""
    from evoscen_record import mcap_internals as MI

    rng = np.random.default_rng(5)
    topics = [spec.name for spec in CONTRACT]
    plan = [(topics[int(rng.integers(0, len(topics)))], bytes(rng.integers(0, 256, int(rng.integers(0, 3000)),
                                                                        dtype=np.uint8)),
             int(k // 3) * 50_000_000 + int(rng.integers(0, 2)) * 7) for k in range(600)]

    def record(name: str, fast: bool) -> bytes:  # the same bag name (the metadata record holds the file's name)
        bag = BagRecorder(tmp_path / name / "bag", CONTRACT, compression=compression, chunk_size=4096,
                          fast_writes=fast)
        for topic, data, t in plan:
            bag.write(topic, data, t, canonical=True)
        bag.close()
        return (tmp_path / name / "bag" / "bag_0.mcap").read_bytes()

    assert MI.FastMessages.usable(BagRecorder(tmp_path / "probe", CONTRACT)._writer)
    fast = record("fast", True)
    assert record("library", False) == fast
    monkeypatch.setattr(MI.FastMessages, "usable", staticmethod(lambda writer: False))  # another mcap: its path
    assert record("other", True) == fast
