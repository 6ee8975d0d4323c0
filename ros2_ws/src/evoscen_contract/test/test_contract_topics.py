"""Tests of evoscen_contract.topics: the contract table, events, odometry, clock."""

from __future__ import annotations

import math

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from evoscen_contract.qos import QosSpec, rosbag2_qos_yaml
from evoscen_contract.topics import (
    CONTRACT,
    POLICY_CODES,
    POLICY_NAMES,
    TOPICS,
    WORLD_FIELDS,
    clock_message,
    contract_markdown,
    events_message,
    odometry_message,
    parse_events,
)
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message


def test_contract_names_types_and_qos() -> None:
    assert list(TOPICS) == [
        "/clock", "/evoscen/world", "/evoscen/commands/bv", "/evoscen/commands/sut",
        "/evoscen/sut/odom", "/evoscen/events", "/evoscen/roster", "/evoscen/markers", "/evoscen/map_markers",
    ]  # fmt: skip
    assert TOPICS["/evoscen/map_markers"].qos.durability == "transient_local"
    assert TOPICS["/evoscen/markers"].type_name == "visualization_msgs/msg/MarkerArray"
    assert TOPICS["/clock"].type_name == "rosgraph_msgs/msg/Clock"
    assert TOPICS["/evoscen/world"].fields == WORLD_FIELDS
    assert len(WORLD_FIELDS) == 17 and WORLD_FIELDS[0] == "id"
    assert TOPICS["/evoscen/commands/bv"].fields == ("id", "throttle", "lane_change")
    assert TOPICS["/evoscen/roster"].fields == ("id", "role", "policy", "length", "width")
    assert TOPICS["/evoscen/roster"].qos.durability == "transient_local"
    assert TOPICS["/clock"].qos.reliability == "reliable"
    for spec in CONTRACT:
        pkg, ns, name = spec.type_name.split("/")
        assert ns == "msg" and spec.msg_class.__name__ == name
        assert spec.msg_class.__module__.startswith(pkg + ".msg")
    assert POLICY_CODES == {"level0": 0, "mutual": 1, "competitive": 2, "cooperative": 3,
                            "sut": 4, "nilsson": 5, "mobil": 6}
    assert POLICY_NAMES[2] == "competitive"
    from evoscen_sim.scenario_builders import POLICY_CODES as SIM_POLICY_CODES

    assert SIM_POLICY_CODES is POLICY_CODES  # one definition (evoscen_contract.contract), no copy


def test_qos_conversions() -> None:
    q = TOPICS["/evoscen/roster"].qos_profile()
    assert isinstance(q, QoSProfile)
    assert q.reliability == ReliabilityPolicy.RELIABLE
    assert q.durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert q.history == HistoryPolicy.KEEP_LAST and q.depth == 1
    be = QosSpec(reliability="best_effort", history="keep_all").to_rclpy()
    assert be.reliability == ReliabilityPolicy.BEST_EFFORT and be.history == HistoryPolicy.KEEP_ALL
    prof = TOPICS["/evoscen/world"].offered_qos_profiles()[0]
    assert list(prof)[:4] == ["history", "depth", "reliability", "durability"]
    assert prof["deadline"] == {"sec": 9223372036, "nsec": 854775807}
    # per-step topics are keep-all (a lagging recorder must not lose samples); rosbag2 writes depth 0
    assert rosbag2_qos_yaml([TOPICS["/clock"].qos]).startswith("- history: keep_all\n  depth: 0\n")
    assert TOPICS["/clock"].qos_profile().history == HistoryPolicy.KEEP_ALL
    with pytest.raises(ValueError):
        QosSpec(reliability="sometimes")
    with pytest.raises(ValueError):
        QosSpec(depth=0)


def test_contract_markdown_lists_every_topic() -> None:
    md = contract_markdown()
    assert md.splitlines()[0] == "| topic | type | publisher | subscribers | QoS | rate | meaning |"
    for spec in CONTRACT:
        if spec.name == "/evoscen/commands/bv":  # one topic per BV node: the default scenario's three
            for part in ("competitive", "mutual", "cooperative"):
                assert f"| `/evoscen/commands/bv_{part}` | `{spec.type_name}` | `evoscen_bv_{part}` |" in md
        else:
            assert f"| `{spec.name}` | `{spec.type_name}` |" in md
    assert "`heading_rel`" in md


def test_bv_command_topics_follow_the_node_names() -> None:
    from evoscen_contract import topics as T

    assert T.command_topic("evoscen_sut") == "/evoscen/commands/sut"
    assert T.bv_command_spec("evoscen_bv") is T.COMMANDS_BV
    spec = T.bv_command_spec(T.bv_node_name("mutual"))
    assert (spec.name, spec.publisher, spec.fields) == ("/evoscen/commands/bv_mutual", "evoscen_bv_mutual",
                                                        T.COMMANDS_BV.fields)
    names = [s.name for s in T.contract_for(["evoscen_bv_competitive", "evoscen_bv_0"])]
    assert names == ["/clock", "/evoscen/world", "/evoscen/commands/bv_competitive", "/evoscen/commands/bv_0",
                     "/evoscen/commands/sut", "/evoscen/sut/odom", "/evoscen/events", "/evoscen/roster",
                     "/evoscen/markers", "/evoscen/map_markers"]
    assert T.contract_for([]) == T.contract_for(["evoscen_bv"]) == CONTRACT
    assert T.spec_of("/evoscen/commands/bv_3").publisher == "evoscen_bv_3"
    assert T.spec_of("/evoscen/nosuch") is None and T.spec_of("/evoscen/commands/bvx") is None


def test_events_round_trip() -> None:
    events = [
        {"name": "evoscen/collision", "level": 2, "message": "BV 3 hit SUT",
         "step": 41, "time_s": 4.1, "ids": [3, 0]},
        {"name": "evoscen/lane_change", "level": 0, "message": "", "step": 41,
         "time_s": 4.1, "ids": [7], "direction": -1, "from_lane": 2, "to_lane": 1,
         "duration_s": 3.0000000000000004},
        {"name": "evoscen/reentry", "level": 1, "message": "", "ids": [], "duration_s": math.inf},
        {"name": "evoscen/fault", "level": 2, "message": "deadline", "controller": "evoscen_bv",
         "misses": 3, "note": "free text"},
    ]  # fmt: skip
    msg = events_message(events, stamp_ns=4_100_000_000)
    back = deserialize_message(serialize_message(msg), DiagnosticArray)
    assert (back.header.stamp.sec, back.header.stamp.nanosec) == (4, 100_000_000)
    assert [s.hardware_id for s in back.status] == ["evoscen"] * 4
    assert parse_events(back) == events
    kv = {v.key: v.value for v in back.status[0].values}
    assert kv == {"step": "41", "time_s": "4.1", "ids": "3,0"}


def test_events_defaults_and_errors() -> None:
    (ev,) = parse_events(events_message([{"name": "evoscen/collision", "ids": (1, 2)}], 0))
    assert ev == {"name": "evoscen/collision", "level": 2, "message": "", "ids": [1, 2]}
    assert parse_events(events_message([], 0)) == []
    with pytest.raises(ValueError, match="name 'evoscen/boom'"):
        events_message([{"name": "evoscen/boom"}], 0)
    with pytest.raises(ValueError, match="'step'"):
        events_message([{"name": "evoscen/fault", "step": 1.5}], 0)
    with pytest.raises(ValueError, match="level"):
        events_message([{"name": "evoscen/fault", "level": 7}], 0)


def test_odometry_and_clock() -> None:
    odom = odometry_message(10.0, -2.5, math.pi / 2, 30.0, 0.1, stamp_ns=1_500_000_000)
    assert odom.header.frame_id == "map" and odom.child_frame_id == "sut/base_link"
    assert (odom.header.stamp.sec, odom.header.stamp.nanosec) == (1, 500_000_000)
    assert odom.pose.pose.position.x == 10.0 and odom.pose.pose.position.y == -2.5
    q = odom.pose.pose.orientation
    assert q.x == 0.0 and q.y == 0.0
    assert q.z == pytest.approx(math.sqrt(0.5)) and q.w == pytest.approx(math.sqrt(0.5))
    assert odom.twist.twist.linear.x == 30.0 and odom.twist.twist.angular.z == 0.1
    clk = clock_message(2_000_000_001)
    assert (clk.clock.sec, clk.clock.nanosec) == (2, 1)


def test_the_contract_section_is_rewritten_between_its_markers(tmp_path) -> None:
    from evoscen_contract.topics import CONTRACT_BEGIN, CONTRACT_END, contract_markdown, contract_section, \
        write_contract_section

    page = tmp_path / "topics.md"
    page.write_text(f"# Topics\n\n{CONTRACT_BEGIN}\n| old |\n{CONTRACT_END}\n\nAfter.\n", encoding="utf-8")
    assert contract_section(page.read_text(encoding="utf-8")) == "| old |"
    assert write_contract_section(page) is True
    table = contract_markdown().strip()
    assert page.read_text(encoding="utf-8") == f"# Topics\n\n{CONTRACT_BEGIN}\n{table}\n{CONTRACT_END}\n\nAfter.\n"
    assert write_contract_section(page) is False
    page.write_text("no markers\n", encoding="utf-8")
    with pytest.raises(ValueError, match="contract markers"):
        write_contract_section(page)
