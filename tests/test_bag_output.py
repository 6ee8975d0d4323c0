"""The recorded bag of ``run_scenario.py --steps 200 --seed 3`` decodes with two independent
readers (rosbags, with its own JAZZY type store; mcap_ros2, with the schemas embedded in the
file) and its content matches the topic contract and the physics of the run.
"""

from __future__ import annotations

import json
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np
import pytest
import yaml
from evoscen_contract.cdr import pad4

pytestmark = [pytest.mark.e2e, pytest.mark.filterwarnings("ignore::DeprecationWarning")]

DT_NS = 100_000_000  # dt_s = 0.1 of the shipped config
N_VEHICLES = 21  # 20 BVs + the SUT

# topics published in every step / once; /evoscen/events after every step plus the run_end event
# the BV nodes of the default config (bvs.nodes: by_policy, 20 BVs at 4:3:3 = 8 + 6 + 6), one topic each
BV_ROWS = {"/evoscen/commands/bv_competitive": 8, "/evoscen/commands/bv_mutual": 6,
           "/evoscen/commands/bv_cooperative": 6}
BV_NODES = [f"evoscen_{t.rsplit('/', 1)[1]}" for t in BV_ROWS]
ALWAYS = {"/clock", "/evoscen/world", *BV_ROWS, "/evoscen/commands/sut",
          "/evoscen/sut/odom", "/evoscen/roster"}


@pytest.fixture(scope="module")
def rosbags_messages(recorded_run):
    """``{topic: [(log_time_ns, msgtype, decoded message), ...]}`` read with rosbags."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    out: dict[str, list] = defaultdict(list)
    with Reader(recorded_run.bag_dir) as reader:
        connections = {c.topic: c for c in reader.connections}
        for conn, t_ns, raw in reader.messages():
            out[conn.topic].append((t_ns, conn.msgtype, store.deserialize_cdr(raw, conn.msgtype)))
        meta = {"message_count": reader.message_count, "connections": connections}
    return out, meta


@pytest.fixture(scope="module")
def mcap_messages(recorded_run):
    """``{topic: [decoded message, ...]}`` read with mcap_ros2 (embedded ros2msg schemas)."""
    from mcap_ros2.reader import read_ros2_messages

    out: dict[str, list] = defaultdict(list)
    for m in read_ros2_messages(str(recorded_run.mcap_path)):
        out[m.channel.topic].append(m)
    return out


def _ns(stamp) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _expected_counts(steps: int) -> dict[str, int]:
    return {
        "/clock": steps + 1,
        "/evoscen/world": steps + 1,
        "/evoscen/sut/odom": steps + 1,
        **dict.fromkeys(BV_ROWS, steps),
        "/evoscen/commands/sut": steps,
        "/evoscen/events": steps + 1,  # one after each step (empty if nothing happened) + run_end
        "/evoscen/roster": 1,
        "/evoscen/markers": steps // 5 + 1,  # every recording.markers_every = 5 steps, t_0 .. t_N
        "/evoscen/map_markers": 1,
    }


# --------------------------------------------------------------------------- rosbags


def test_rosbags_topics_types_and_counts(recorded_run, rosbags_messages):
    from evoscen_contract import topics as T

    messages, meta = rosbags_messages
    steps = recorded_run.steps
    # every contract topic is declared (events too, even if empty), with the contract's type
    assert {name: c.msgtype for name, c in meta["connections"].items()} == {
        spec.name: spec.type_name for spec in T.contract_for(BV_NODES)}
    for _name, conn in meta["connections"].items():
        assert conn.ext.serialization_format == "cdr"
    present = set(messages)
    assert ALWAYS <= present <= {spec.name for spec in T.contract_for(BV_NODES)}
    s = recorded_run.summary
    counts = {topic: len(v) for topic, v in messages.items()}
    assert counts == _expected_counts(steps)
    assert meta["message_count"] == sum(counts.values()) == s["messages"]
    assert {c.topic: c.msgcount for c in meta["connections"].values() if c.msgcount} == counts


def test_rosbags_stamps_and_clock(recorded_run, rosbags_messages):
    messages, _ = rosbags_messages
    steps = recorded_run.steps

    clock = messages["/clock"]
    assert [_ns(m.clock) for _, _, m in clock] == [k * DT_NS for k in range(steps + 1)]
    assert [t for t, _, _ in clock] == [k * DT_NS for k in range(steps + 1)]  # log time = sim time
    assert np.all(np.diff([_ns(m.clock) for _, _, m in clock]) == DT_NS)  # +0.1 s exactly

    for topic in ("/evoscen/world", "/evoscen/sut/odom"):
        stamps = [_ns(m.header.stamp) for _, _, m in messages[topic]]
        assert stamps == [k * DT_NS for k in range(steps + 1)], topic
        assert [t for t, _, _ in messages[topic]] == stamps
        assert {m.header.frame_id for _, _, m in messages[topic]} == {"map"}
    for topic in (*BV_ROWS, "/evoscen/commands/sut"):
        stamps = [_ns(m.header.stamp) for _, _, m in messages[topic]]
        assert stamps == [k * DT_NS for k in range(steps)], topic  # answer to the world at t_k
    (_, _, roster), = messages["/evoscen/roster"]
    assert _ns(roster.header.stamp) == 0
    for t, _, m in messages.get("/evoscen/events", []):
        # stamped t_{k+1}: after a step, within the run
        assert _ns(m.header.stamp) == t and 0 < t <= steps * DT_NS and t % DT_NS == 0


def test_rosbags_tables(recorded_run, rosbags_messages):
    from evoscen_contract import topics as T
    from evoscen_contract.tables import table_columns, table_fields

    messages, _ = rosbags_messages
    for _, _, m in messages["/evoscen/world"]:
        assert table_fields(m) == T.WORLD_FIELDS
        cols = table_columns(m)
        assert len(cols["id"]) == N_VEHICLES
        assert sorted(cols["id"].tolist()) == list(range(N_VEHICLES))
    for topic, rows in (*BV_ROWS.items(), ("/evoscen/commands/sut", 1)):
        for _, _, m in messages[topic]:
            assert table_fields(m) == T.COMMAND_FIELDS
            cols = table_columns(m)
            assert len(cols["id"]) == rows
            assert np.all(np.abs(cols["throttle"]) <= 1.0)
            assert set(cols["lane_change"].tolist()) <= {-1.0, 0.0, 1.0}
        ids = {tuple(table_columns(m)["id"].tolist()) for _, _, m in messages[topic]}
        assert len(ids) == 1 and (ids == {(0.0,)} if rows == 1 else 0.0 not in next(iter(ids)))
    (_, _, roster), = messages["/evoscen/roster"]
    assert table_fields(roster) == T.ROSTER_FIELDS
    r = table_columns(roster)
    assert sorted(r["id"].tolist()) == list(range(N_VEHICLES))
    assert r["role"][r["id"] == 0].tolist() == [T.ROLE_SUT]
    assert sorted(r["role"].tolist()) == [T.ROLE_BV] * (N_VEHICLES - 1) + [T.ROLE_SUT]


def test_rosbags_odometry_matches_world(rosbags_messages):
    from evoscen_contract.tables import table_columns

    messages, _ = rosbags_messages
    for (_, _, w), (_, _, o) in zip(messages["/evoscen/world"], messages["/evoscen/sut/odom"], strict=True):
        cols = table_columns(w)
        sut = int(np.flatnonzero(cols["id"] == 0)[0])
        assert o.child_frame_id == "sut/base_link"
        assert o.pose.pose.position.x == cols["x"][sut]
        assert o.pose.pose.position.y == cols["y"][sut]
        assert o.twist.twist.linear.x == cols["speed"][sut]
        q = o.pose.pose.orientation
        assert 2.0 * np.arctan2(q.z, q.w) == pytest.approx(cols["yaw"][sut], abs=1e-12)


def test_rosbags_events(recorded_run, rosbags_messages):
    from evoscen_contract import topics as T

    messages, _ = rosbags_messages
    events = [e for _, _, m in messages.get("/evoscen/events", []) for e in T.parse_events(m)]
    names = Counter(e["name"] for e in events)
    assert set(names) <= set(T.EVENT_NAMES)
    s = recorded_run.summary
    assert names[T.EVENT_LANE_CHANGE] == s["lane_changes"]
    assert names[T.EVENT_COLLISION] == s["collisions"]
    assert names[T.EVENT_REENTRY] == s["reentries"]
    assert names[T.EVENT_OFF_ROAD] == s["off_road"]
    # the summary's SUT count is the SUT's completed lane changes, the report's
    report = json.loads((recorded_run.out / "report" / "report.json").read_text())
    sut_id = report["run"]["sut_id"]
    assert s["sut_lane_changes"] == report["efficiency"]["lane_changes"] == sum(
        1 for e in events if e["name"] == T.EVENT_LANE_CHANGE and e["ids"] == [sut_id] and e.get("kind") == "completed")
    assert names[T.EVENT_RUN_END] == 1  # the last message, kind completed
    last = T.parse_events(messages["/evoscen/events"][-1][2])
    assert [(e["name"], e["kind"], e["steps"]) for e in last] == [(T.EVENT_RUN_END, "completed", recorded_run.steps)]
    for t, _, m in messages.get("/evoscen/events", []):
        for e in T.parse_events(m):
            assert e["time_s"] == pytest.approx(t / 1e9)
            assert e["step"] == round(t / DT_NS)
            if e["name"] == T.EVENT_LANE_CHANGE:
                assert abs(e["to_lane"] - e["from_lane"]) == 1
                assert e["direction"] == e["to_lane"] - e["from_lane"]
                assert all(0 <= i < N_VEHICLES for i in e["ids"])


def test_rosbags_schema_text_is_self_sufficient(recorded_run):
    """rosbags, fed only the ros2msg schema text embedded in the MCAP, decodes every message the
    same way as with its own JAZZY store (the embedded definitions are complete and correct)."""
    from mcap.reader import make_reader
    from rosbags.typesys import Stores, get_typestore
    from rosbags.typesys.msg import get_types_from_msg

    with open(recorded_run.mcap_path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        embedded = get_typestore(Stores.EMPTY)
        for schema in summary.schemas.values():
            text = schema.data.decode("utf-8")
            # ros2msg schema: main definition, then "=====\nMSG: pkg/msg/Type\n..." sections
            parts = text.split("=" * 80 + "\n")
            types = get_types_from_msg(parts[0], schema.name)
            for part in parts[1:]:
                header, _, body = part.partition("\n")
                assert header.startswith("MSG: "), header
                types.update(get_types_from_msg(body, header[5:].strip()))
            embedded.register(types)
        jazzy = get_typestore(Stores.ROS2_JAZZY)
        n = 0
        for schema, _channel, message in reader.iter_messages():
            a = embedded.deserialize_cdr(message.data, schema.name)
            b = jazzy.deserialize_cdr(message.data, schema.name)
            # stored bytes = re-serialized bytes padded with zeros to 4 bytes (as DDS sends them)
            assert pad4(bytes(jazzy.serialize_cdr(b, schema.name))) == bytes(message.data)
            assert pad4(bytes(embedded.serialize_cdr(a, schema.name))) == bytes(message.data)
            n += 1
    assert n == summary.statistics.message_count


# --------------------------------------------------------------------------- mcap / mcap_ros2


def test_mcap_summary_and_channels(recorded_run, mcap_messages):
    from evoscen_contract import topics as T
    from mcap.reader import make_reader

    with open(recorded_run.mcap_path, "rb") as f:
        reader = make_reader(f)
        header = reader.get_header()
        summary = reader.get_summary()
    assert header.profile == "ros2"
    assert summary is not None and summary.statistics is not None
    total = sum(len(v) for v in mcap_messages.values())
    assert summary.statistics.message_count == total == recorded_run.summary["messages"]
    assert summary.statistics.message_start_time == 0
    assert summary.statistics.message_end_time == recorded_run.steps * DT_NS
    assert summary.statistics.channel_count == len(T.contract_for(BV_NODES))
    per_channel = {summary.channels[cid].topic: n for cid, n in summary.statistics.channel_message_counts.items()}
    assert per_channel == {topic: len(v) for topic, v in mcap_messages.items()}

    assert {c.topic for c in summary.channels.values()} == {s.name for s in T.contract_for(BV_NODES)}
    for channel in summary.channels.values():
        spec = T.spec_of(channel.topic)
        assert channel.message_encoding == "cdr"
        schema = summary.schemas[channel.schema_id]
        assert schema.encoding == "ros2msg"
        assert schema.name == spec.type_name
        assert schema.data  # a definition is embedded
        assert "offered_qos_profiles" in channel.metadata
        assert yaml.safe_load(channel.metadata["offered_qos_profiles"]) == spec.offered_qos_profiles()
    roster_qos = yaml.safe_load(next(c for c in summary.channels.values()
                                     if c.topic == T.ROSTER.name).metadata["offered_qos_profiles"])
    assert roster_qos[0]["durability"] == "transient_local"


def test_mcap_ros2_decodes_everything(recorded_run, mcap_messages, rosbags_messages):
    from evoscen_contract import topics as T
    from evoscen_contract.tables import table_array

    rb, _ = rosbags_messages
    assert set(mcap_messages) == set(rb)
    for topic, msgs in mcap_messages.items():
        assert len(msgs) == len(rb[topic])
        for m in msgs:
            assert m.schema.encoding == "ros2msg" and m.channel.message_encoding == "cdr"
            assert m.schema.name == T.spec_of(topic).type_name
            assert m.ros_msg is not None
            assert m.log_time_ns == m.publish_time_ns
    # both readers decode the tables to the same numbers
    for topic in ("/evoscen/world", *BV_ROWS, "/evoscen/commands/sut", "/evoscen/roster"):
        for m, (_, _, r) in zip(mcap_messages[topic], rb[topic], strict=True):
            assert np.array_equal(table_array(m.ros_msg), table_array(r))
            assert _ns(m.ros_msg.header.stamp) == _ns(r.header.stamp) == m.log_time_ns
    for m, (_, _, r) in zip(mcap_messages["/clock"], rb["/clock"], strict=True):
        assert _ns(m.ros_msg.clock) == _ns(r.clock)
    for m, (_, _, r) in zip(mcap_messages.get("/evoscen/events", []), rb.get("/evoscen/events", []), strict=True):
        assert T.parse_events(m.ros_msg) == T.parse_events(r)


# --------------------------------------------------------------------------- physics


def test_world_physics_consistency(recorded_run, mcap_messages):
    from evoscen_contract import topics as T
    from evoscen_contract.tables import table_columns
    from evoscen_sim.config.scenario_config import load_scenario_config

    cfg = load_scenario_config(recorded_run.out / "scenario.yaml")
    dt = cfg.dt_s
    assert round(dt * 1e9) == DT_NS
    tables = []
    for m in mcap_messages["/evoscen/world"]:
        cols = table_columns(m.ros_msg)
        order = np.argsort(cols["id"])
        tables.append({k: v[order] for k, v in cols.items()})
    assert len(tables) == recorded_run.steps + 1

    # new trips (window entries, re-entries) and window shifts, from the bag's own events
    entered: dict[int, set[int]] = {}
    shifted: dict[int, float] = {}
    for m in mcap_messages["/evoscen/events"]:
        for st in m.ros_msg.status:
            kv = {x.key: x.value for x in st.values}
            if st.name == "evoscen/reentry":
                entered.setdefault(int(kv["step"]), set()).update(int(i) for i in kv["ids"].split(",") if i)
            elif st.name == "evoscen/shift":
                shifted[int(kv["step"])] = float(kv["shift_m"])
    checked = 0
    for k, w in enumerate(tables):
        assert w["id"].tolist() == list(range(N_VEHICLES))
        assert w["role"][0] == T.ROLE_SUT and np.all(w["role"][1:] == T.ROLE_BV)
        assert set(w["lane"].tolist()) <= {0.0, 1.0, 2.0, 3.0, 4.0}
        assert set(w["target_lane"].tolist()) <= {0.0, 1.0, 2.0, 3.0, 4.0}
        assert np.all(np.abs(w["target_lane"] - w["lane"]) <= 1)
        assert set(w["lane_change"].tolist()) <= {-1.0, 0.0, 1.0}
        assert np.all((w["speed"] >= 0) & (w["speed"] <= cfg.vehicle.max_speed_mps))
        assert np.all((w["accel"] >= -cfg.vehicle.max_brake_mps2 - 1e-9)
                      & (w["accel"] <= cfg.vehicle.max_accel_mps2 + 1e-9))
        assert np.all(w["d"] < 0)  # all lanes are right of the reference line
        # bodies: the SUT the vehicle section's; under the default highd make-up each BV slot keeps the body it
        # was drawn (cars up to 6.9 m at the vehicle section's width, trucks of 7.1 m or more, 2.5 m wide)
        assert (w["length"][0], w["width"][0]) == (cfg.vehicle.length_m, cfg.vehicle.width_m)
        assert np.array_equal(w["length"], tables[0]["length"]) and np.array_equal(w["width"], tables[0]["width"])
        truck = w["length"][1:] > 7.0
        assert np.all(w["width"][1:][truck] == 2.5) and np.all(w["width"][1:][~truck] == cfg.vehicle.width_m)
        assert np.all(w["length"][1:][~truck] <= 6.9) and np.all(w["length"][1:][truck] >= 7.1)
        if k == 0:
            continue
        prev = tables[k - 1]
        ds = w["s"] - prev["s"] + shifted.get(k, 0.0)  # a shift moves every vehicle back by shift_m
        moving_on = ~np.isin(w["id"], list(entered.get(k, ())))  # an entering vehicle starts a new trip
        # s advances by about speed * dt (mean of the two speeds: the speed changes by at most
        # max_accel * dt within a step; the road curvature changes the projection onto the
        # reference line by well under 2 %, the heading relative to the road by 1 - cos(psi))
        v_mean = 0.5 * (w["speed"] + prev["speed"])
        psi = np.maximum(np.abs(w["heading_rel"]), np.abs(prev["heading_rel"]))
        # + a vehicle that comes to rest within the step travels less than the mean speed says (<= b dt² / 4)
        tol = (0.02 + (1.0 - np.cos(psi))) * v_mean * dt + 0.25 * cfg.vehicle.max_brake_mps2 * dt**2 + 1e-6
        assert np.all(np.abs(ds - v_mean * dt)[moving_on] <= tol[moving_on]), (k, ds, v_mean * dt)
        assert np.all(np.abs(w["speed"] - prev["speed"])[moving_on] <= cfg.vehicle.max_brake_mps2 * dt + 1e-9)
        checked += int(moving_on.sum())
    assert checked >= 0.95 * N_VEHICLES * recorded_run.steps
    if recorded_run.summary["reentries"] == 0:
        assert checked == N_VEHICLES * recorded_run.steps
    # the SUT row of the first world table is the configured start (the warm-up holds it there and
    # changes only its speed, which the lane keeper drove: traffic.warmup_s)
    assert tables[0]["lane"][0] == cfg.sut.lane
    assert tables[0]["s"][0] == pytest.approx(cfg.sut.s_m)
    assert 0.0 < tables[0]["speed"][0] <= cfg.vehicle.max_speed_mps


def test_metadata_yaml_matches_bag(recorded_run, mcap_messages):
    from evoscen_contract import topics as T

    meta = yaml.safe_load((recorded_run.bag_dir / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["version"] == 9
    assert meta["ros_distro"] == "jazzy"
    topics = {t["topic_metadata"]["name"]: t for t in meta["topics_with_message_count"]}
    assert set(topics) == {s.name for s in T.contract_for(BV_NODES)}
    for name, t in topics.items():
        spec = T.spec_of(name)
        assert t["topic_metadata"]["type"] == spec.type_name
        assert t["topic_metadata"]["serialization_format"] == "cdr"
        assert t["topic_metadata"]["offered_qos_profiles"] == spec.offered_qos_profiles()
        assert t["message_count"] == len(mcap_messages.get(name, []))
    assert meta["files"][0]["path"] == "bag_0.mcap"
    assert meta["files"][0]["message_count"] == meta["message_count"]


def test_bag_dir_contains_only_the_bag(recorded_run):
    assert sorted(p.name for p in Path(recorded_run.bag_dir).iterdir()) == ["bag_0.mcap", "metadata.yaml"]
