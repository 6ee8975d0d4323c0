"""Tests of evoscen_eval.scenes.replay, the ROS-free core of ``scripts/replay.py``.

Bags are written with our recorder (the contract's QoS) and with ``rosbags`` (another
writer: rosbag2 metadata version 8, QoS policies as enum integers); expectations are the
profiles that were written.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from rclpy.serialization import serialize_message

from evoscen_contract.qos import QosSpec, rosbag2_qos_yaml
from evoscen_contract.topics import (
    CLOCK,
    CONTRACT,
    LATCHED_QOS,
    ROSTER,
    STEP_QOS,
    TOPICS,
    clock_message,
)
from evoscen_record.recorder import BagRecorder
from evoscen_eval.scenes.replay import (
    DEFAULT_QOS,
    Pacer,
    iter_replay,
    message_class_path,
    parse_offered_qos,
    parse_rate,
    parse_seconds,
    read_bag_topics,
    select_topics,
)
from evoscen_sim.errors import InputError

BEST_EFFORT_5 = QosSpec(reliability="best_effort", durability="volatile", history="keep_last", depth=5)


# ------------------------------------------------------------------ QoS


def test_offered_qos_v9_list_and_yaml_string() -> None:
    for spec in (STEP_QOS, LATCHED_QOS, BEST_EFFORT_5):
        assert parse_offered_qos([spec.to_rosbag2()]) == spec
        assert parse_offered_qos(rosbag2_qos_yaml([spec])) == spec
        assert parse_offered_qos(rosbag2_qos_yaml([spec]).encode()) == spec


def test_offered_qos_v8_enum_integers() -> None:
    # rosbag2 <= Humble / rosbags v8: history 1 keep_last 2 keep_all; reliability 1 reliable 2 best_effort;
    # durability 1 transient_local 2 volatile
    text = "- history: 2\n  depth: 0\n  reliability: 1\n  durability: 1\n"
    assert parse_offered_qos(text) == QosSpec("reliable", "transient_local", "keep_all", 0)
    assert parse_offered_qos([{"history": 1, "depth": 7, "reliability": 2, "durability": 2}]) == \
        QosSpec("best_effort", "volatile", "keep_last", 7)


def test_offered_qos_defaults() -> None:
    assert parse_offered_qos(None) == DEFAULT_QOS
    assert parse_offered_qos("") == DEFAULT_QOS
    assert parse_offered_qos("[]") == DEFAULT_QOS
    # system_default everywhere, keep_last with depth 0 -> rclcpp's defaults
    assert parse_offered_qos([{"history": "system_default", "depth": 0, "reliability": "system_default",
                               "durability": "system_default"}]) == DEFAULT_QOS
    assert parse_offered_qos([{"history": "keep_last", "depth": 0}]) == DEFAULT_QOS
    # keep_all ignores the depth
    assert parse_offered_qos([{"history": "keep_all", "depth": 100}]).depth == 0


def test_offered_qos_several_offers_are_adapted() -> None:
    # reliable only if all are, transient_local only if all are, keep_all if any, else the largest depth
    offers = [LATCHED_QOS.to_rosbag2(), BEST_EFFORT_5.to_rosbag2()]
    assert parse_offered_qos(offers) == QosSpec("best_effort", "volatile", "keep_last", 5)
    offers = [LATCHED_QOS.to_rosbag2(), STEP_QOS.to_rosbag2()]
    assert parse_offered_qos(offers) == QosSpec("reliable", "volatile", "keep_all", 0)
    assert parse_offered_qos([STEP_QOS.to_rosbag2()] * 3) == STEP_QOS


@pytest.mark.parametrize("value, needle", [
    ("- history: keep_some\n", "history = 'keep_some'"),
    ([{"reliability": "very"}], "reliability = 'very'"),
    ([{"durability": 9}], "durability = 9"),
    ([{"history": "keep_last", "depth": -1}], "depth = -1"),
    ("{unclosed", "not YAML"),
    ("42", "expected a list"),
    (["x"], "expected a mapping"),
])
def test_offered_qos_errors_name_the_key(value, needle) -> None:
    with pytest.raises(InputError, match="bag 'b': topic '/t'") as info:
        parse_offered_qos(value, "bag 'b': topic '/t'")
    assert needle in str(info.value)
    assert "\n" not in str(info.value)


# ------------------------------------------------------------------ bags


def _record(bag_dir: Path, order=((0, CLOCK.name), (1, CLOCK.name))) -> Path:
    """A contract bag: the roster at t=0, then /clock messages at the given (step, topic) in file order."""
    import numpy as np

    from evoscen_contract.tables import table_message

    with BagRecorder(bag_dir, CONTRACT) as bag:
        bag.write_message(ROSTER.name, table_message(ROSTER.fields, np.zeros((2, len(ROSTER.fields))), 0, "map"), 0)
        for k, topic in order:
            bag.write_message(topic, clock_message(k * 100_000_000), k * 100_000_000)
    return bag_dir


def test_read_bag_topics_of_our_bag(tmp_path: Path) -> None:
    topics = read_bag_topics(_record(tmp_path / "bag"))
    assert [t.name for t in topics] == [s.name for s in CONTRACT]
    for t in topics:
        spec = TOPICS[t.name]
        assert (t.type_name, t.encoding, t.qos) == (spec.type_name, "cdr", spec.qos)
    counts = {t.name: t.message_count for t in topics}
    assert counts[CLOCK.name] == 2 and counts[ROSTER.name] == 1 and counts["/evoscen/world"] == 0
    # the .mcap file alone works too
    assert read_bag_topics(tmp_path / "bag" / "bag_0.mcap") == topics


def test_read_bag_topics_of_a_rosbags_bag(tmp_path: Path) -> None:
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    inf = QosTime(sec=2**31 - 1, nsec=0)
    qos = Qos(QosHistory.KEEP_LAST, 5, QosReliability.BEST_EFFORT, QosDurability.VOLATILE, inf, inf,
              QosLiveliness.AUTOMATIC, inf, False)
    msg = store.types["std_msgs/msg/String"](data="hello")
    with Writer(tmp_path / "rb", version=8, storage_plugin=StoragePlugin.MCAP) as w:
        conn = w.add_connection("/chatter", "std_msgs/msg/String", typestore=store, offered_qos_profiles=[qos])
        plain = w.add_connection("/plain", "std_msgs/msg/String", typestore=store)
        for k in range(3):
            w.write(conn, 10 + k, store.serialize_cdr(msg, "std_msgs/msg/String"))
        w.write(plain, 5, store.serialize_cdr(msg, "std_msgs/msg/String"))
    topics = {t.name: t for t in read_bag_topics(tmp_path / "rb")}
    assert topics["/chatter"].qos == BEST_EFFORT_5
    assert topics["/chatter"].type_name == "std_msgs/msg/String" and topics["/chatter"].message_count == 3
    assert topics["/plain"].qos == DEFAULT_QOS  # no recorded offer
    assert [(t, ns) for t, ns, _ in iter_replay(tmp_path / "rb", ["/chatter", "/plain"])] == \
        [("/plain", 5), ("/chatter", 10), ("/chatter", 11), ("/chatter", 12)]


def test_iter_replay_is_in_log_time_order_and_filters(tmp_path: Path) -> None:
    bag = _record(tmp_path / "bag", order=((3, CLOCK.name), (1, CLOCK.name), (2, CLOCK.name)))
    assert [ns for _, ns, _ in iter_replay(bag, [CLOCK.name])] == [100_000_000, 200_000_000, 300_000_000]
    got = list(iter_replay(bag, [ROSTER.name, CLOCK.name]))
    assert [t for t, _, _ in got] == [ROSTER.name] + [CLOCK.name] * 3
    assert got[1][2] == bytes(serialize_message(clock_message(100_000_000)))  # the recorded bytes


def test_read_bag_topics_errors_name_the_path(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such bag"):
        read_bag_topics(tmp_path / "missing")
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "bad_0.mcap").write_bytes(b"\x89MCAP0\r\n" + b"garbage" * 10)
    with pytest.raises(InputError, match=str(bad)):
        read_bag_topics(bad)
    meta = tmp_path / "meta"
    meta.mkdir()
    (meta / "metadata.yaml").write_text(yaml.safe_dump({"x": 1}))
    with pytest.raises(InputError, match="metadata.yaml"):
        read_bag_topics(meta)


# ------------------------------------------------------------------ arguments


def test_select_topics(tmp_path: Path) -> None:
    topics = read_bag_topics(_record(tmp_path / "bag"))
    assert select_topics(topics, None) == topics
    # bag order, duplicates once
    assert [t.name for t in select_topics(topics, [ROSTER.name, CLOCK.name, CLOCK.name])] == [CLOCK.name, ROSTER.name]
    with pytest.raises(InputError) as info:
        select_topics(topics, ["/nope", CLOCK.name], bag="bag 'x'")
    text = str(info.value)
    assert text.startswith("--topics /nope: not in bag 'x'") and all(s.name in text for s in CONTRACT)


def test_message_class_path() -> None:
    assert message_class_path("sensor_msgs/msg/PointCloud2") == ("sensor_msgs.msg", "PointCloud2")
    assert message_class_path("std_msgs/String") == ("std_msgs.msg", "String")
    for bad in ("PointCloud2", "a/srv/B", "a/msg/B/C", "a-b/msg/C", ""):
        with pytest.raises(InputError, match="pkg/msg/Type"):
            message_class_path(bad)


def test_parse_rate_and_seconds() -> None:
    assert parse_rate("0") == 0.0 and parse_rate("2.5") == 2.5 and parse_rate(1) == 1.0
    for bad in ("-1", "abc", "nan", "inf", "", None):
        with pytest.raises(InputError, match="--rate"):
            parse_rate(bad)
    assert parse_seconds("--start-delay", "0.5") == 0.5
    with pytest.raises(InputError, match="--start-delay -1"):
        parse_seconds("--start-delay", "-1")


# ------------------------------------------------------------------ pacing


class FakeClock:
    """A clock that only moves when slept on."""

    def __init__(self) -> None:
        self.now = 100.0
        self.sleeps: list[float] = []

    def clock(self) -> float:
        return self.now

    def sleep(self, s: float) -> None:
        self.sleeps.append(s)
        self.now += s


@pytest.mark.parametrize("rate, expected", [(1.0, [0.0, 0.1, 0.3, 0.3]), (2.0, [0.0, 0.05, 0.15, 0.15]),
                                            (0.5, [0.0, 0.2, 0.6, 0.6]), (0.0, [0.0, 0.0, 0.0, 0.0])])
def test_pacer_spaces_messages_by_simulation_time(rate, expected) -> None:
    fc = FakeClock()
    pacer = Pacer(rate, clock=fc.clock, sleep=fc.sleep)
    times = []
    for log_ns in (5_000_000_000, 5_100_000_000, 5_300_000_000, 5_300_000_000):
        pacer.wait(log_ns)
        times.append(fc.now - 100.0)
    assert times == pytest.approx(expected)
    # a new pass starts at once, whatever the log time
    pacer.restart()
    before = fc.now
    pacer.wait(5_000_000_000)
    assert fc.now == before


def test_pacer_does_not_sleep_when_late() -> None:
    fc = FakeClock()
    pacer = Pacer(1.0, clock=fc.clock, sleep=fc.sleep)
    pacer.wait(0)
    fc.now += 1.0  # publishing took longer than the gap
    pacer.wait(500_000_000)
    assert fc.sleeps == []
    pacer.wait(2_000_000_000)
    assert fc.sleeps == [pytest.approx(1.0)]
    with pytest.raises(InputError):
        Pacer(-1.0)
