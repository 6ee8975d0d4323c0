"""An outside view of the node graph: a user's own ROS 2 node, written only from the topic contract.

The test reads the topic contract table of docs/topics.md (topic, type, QoS) and column table, and
starts a plain rclpy node in a separate process (its source is written to ``tmp_path`` below;
it imports only rclpy, the standard message packages and numpy: nothing of evoscen, which is
also taken off its ``PYTHONPATH``). That node subscribes to every topic of the table with the
QoS the table states, decodes every message (tables by their PointField descriptions, events,
odometry, clock), and writes a JSON summary once it has seen the ``run_end`` event. It runs on
the graph's domain (reserved on the host by the test and handed to the launcher with
``--domain-id`` and ``EVOSCEN_DOMAIN_RESERVED``, localhost discovery) and is started before the
launcher. Half-way into the run it also subscribes to the roster a second time,
to check that a late joiner gets the latched (transient-local) roster.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.e2e
TOPICS_PAGE = REPO / "docs" / "topics.md"
STEPS = 200
N_VEHICLES = 21  # 1 SUT + 20 BVs (the shipped default scenario)

SUBSCRIBER = r'''
"""A user's observer node: subscribes to the evoscen topics (from the table of docs/topics.md), decodes them."""
import importlib
import json
import sys
import time

import numpy as np
import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

# sensor_msgs/PointField datatypes
POINTFIELD_DTYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}


def qos_from_text(text):
    """'reliable, transient_local, keep_last(1)' -> QoSProfile."""
    reliability, durability, history = [part.strip() for part in text.split(",")]
    kw = {"reliability": {"reliable": ReliabilityPolicy.RELIABLE,
                          "best_effort": ReliabilityPolicy.BEST_EFFORT}[reliability],
          "durability": {"volatile": DurabilityPolicy.VOLATILE,
                         "transient_local": DurabilityPolicy.TRANSIENT_LOCAL}[durability]}
    if history == "keep_all":
        return QoSProfile(history=HistoryPolicy.KEEP_ALL, depth=1, **kw)
    depth = int(history[len("keep_last("):-1])
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth, **kw)


def message_class(type_name):
    package, _msg, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


def stamp_ns(t):
    return int(t.sec) * 1_000_000_000 + int(t.nanosec)


def read_points(msg):
    """PointCloud2 -> structured numpy array, from msg.fields / point_step (like read_points)."""
    names, formats, offsets = [], [], []
    endian = ">" if msg.is_bigendian else "<"
    for f in msg.fields:
        base = endian + POINTFIELD_DTYPES[f.datatype]
        names.append(f.name)
        formats.append(base if f.count == 1 else (base, f.count))
        offsets.append(f.offset)
    dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": msg.point_step})
    rows = msg.width * msg.height
    return np.frombuffer(memoryview(msg.data), dtype=dtype, count=rows)


class Observer(Node):
    def __init__(self, topics):
        super().__init__("user_observer")
        self.topics = topics
        self.summary = {t["name"]: {"type": t["type"], "count": 0, "stamps": []} for t in topics}
        self.summary["late_roster"] = {"count": 0, "rows": [], "columns": None, "after_world_step": None}
        self.run_end = None
        self.late = None
        self.keep = []
        for t in topics:
            self.keep.append(self.create_subscription(message_class(t["type"]), t["name"],
                                                      lambda msg, name=t["name"]: self.on_message(name, msg),
                                                      qos_from_text(t["qos"])))

    def on_message(self, name, msg):
        s = self.summary[name]
        s["count"] += 1
        typ = s["type"]
        if typ == "rosgraph_msgs/msg/Clock":
            s["stamps"].append(stamp_ns(msg.clock))
            s["last_clock_ns"] = stamp_ns(msg.clock)
            return
        if hasattr(msg, "header"):
            s["stamps"].append(stamp_ns(msg.header.stamp))
            s.setdefault("frame_ids", [])
            if msg.header.frame_id not in s["frame_ids"]:
                s["frame_ids"].append(msg.header.frame_id)
        if typ == "sensor_msgs/msg/PointCloud2":
            table = read_points(msg)
            s["columns"] = list(table.dtype.names)
            s.setdefault("rows", [])
            if table.shape[0] not in s["rows"]:
                s["rows"].append(int(table.shape[0]))
            s["all_finite"] = s.get("all_finite", True) and all(
                bool(np.isfinite(table[c]).all()) for c in table.dtype.names)
            if "id" in table.dtype.names:
                ids = sorted(int(i) for i in table["id"])
                s["ids"] = ids if s.get("ids") in (None, ids) else "changing"
            if "speed" in table.dtype.names:
                s["max_speed"] = max(s.get("max_speed", 0.0), float(table["speed"].max()))
            if name.endswith("/world") and self.late is None and stamp_ns(msg.header.stamp) >= 5 * 100_000_000:
                self.subscribe_late(stamp_ns(msg.header.stamp))
        elif typ == "diagnostic_msgs/msg/DiagnosticArray":
            s.setdefault("names", [])
            for status in msg.status:
                if status.name not in s["names"]:
                    s["names"].append(status.name)
                values = {kv.key: kv.value for kv in status.values}
                if status.name == "evoscen/run_end":
                    self.run_end = values
                    s["run_end"] = values
        elif typ == "nav_msgs/msg/Odometry":
            s["child_frame_id"] = msg.child_frame_id
            s["last_speed"] = msg.twist.twist.linear.x
            s["max_odom_speed"] = max(s.get("max_odom_speed", 0.0), msg.twist.twist.linear.x)
            q = msg.pose.pose.orientation
            s["unit_quaternion"] = s.get("unit_quaternion", True) and abs(q.x**2 + q.y**2 + q.z**2 + q.w**2 - 1) < 1e-9

    def subscribe_late(self, t_ns):
        """A second roster subscription, created mid-run (a late joiner)."""
        roster = next(t for t in self.topics if t["name"] == "/evoscen/roster")
        self.summary["late_roster"]["after_world_step"] = t_ns // 100_000_000
        self.late = self.create_subscription(message_class(roster["type"]), roster["name"], self.on_late_roster,
                                             qos_from_text(roster["qos"]))

    def on_late_roster(self, msg):
        s = self.summary["late_roster"]
        table = read_points(msg)
        s["count"] += 1
        s["rows"].append(int(table.shape[0]))
        s["columns"] = list(table.dtype.names)


def main():
    config = json.loads(open(sys.argv[1]).read())
    rclpy.init()
    node = Observer(config["topics"])
    open(config["ready"], "w").close()
    deadline = time.monotonic() + config["timeout_s"]
    end_seen = None
    last_count, last_change = -1, time.monotonic()
    while rclpy.ok() and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
        now = time.monotonic()
        count = sum(v["count"] for v in node.summary.values())
        if count != last_count:
            last_count, last_change = count, now
        if node.run_end is not None and end_seen is None:
            end_seen = now
        # after run_end: until nothing more comes for a second (other topics may still be in flight)
        if end_seen is not None and now - last_change > 1.0 and now - end_seen > 1.0:
            break
    node.summary["timed_out"] = end_seen is None
    node.summary["evoscen_imported"] = sorted(m for m in sys.modules if m.startswith("evoscen"))
    with open(config["out"], "w") as f:
        json.dump(node.summary, f)
    node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()
'''


def topics_page_contract() -> tuple[list[dict], dict[str, list[str]]]:
    """The topic table of docs/topics.md (by its header: topic, type, QoS, publisher, rate, meaning) and table
    columns."""
    text = TOPICS_PAGE.read_text(encoding="utf-8")
    block = text.split("<!-- contract:begin -->", 1)[1].split("<!-- contract:end -->", 1)[0]
    topics, columns, header = [], {}, None

    def cells(line: str) -> list[str]:
        return [c.strip() for c in line.strip().strip("|").split("|")]

    for line in block.splitlines():
        if not line.startswith("|"):
            header = None if not line.strip() else header
        elif header is None:
            header = cells(line)
        elif line.startswith("| `"):
            row = dict(zip(header, cells(line)))
            if "topic" in header and "QoS" in header:
                topics.append({"name": row["topic"].strip("`"), "type": row["type"].strip("`"), "qos": row["QoS"],
                               "publisher": row["publisher"].strip("`"), "rate": row["rate"],
                               "meaning": row["meaning"]})
            elif header == ["table", "columns"]:
                columns[row["table"].strip("`")] = [c.strip().strip("`") for c in row["columns"].split(",")]
    return topics, columns


def _observer_env(domain_id: int) -> dict[str, str]:
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["RMW_IMPLEMENTATION"] = "rmw_fastrtps_cpp"
    env.pop("ROS_LOCALHOST_ONLY", None)
    # a user's node: rclpy and the message packages, not the evoscen workspace
    env["PYTHONPATH"] = os.pathsep.join(p for p in env.get("PYTHONPATH", "").split(os.pathsep)
                                        if p and "evoscen" not in p and "ros2_ws" not in p)
    return env


def test_readme_table_parses():
    topics, columns = topics_page_contract()
    names = [t["name"] for t in topics]
    for expected in ("/clock", "/evoscen/world", "/evoscen/commands/bv_competitive", "/evoscen/commands/bv_mutual",
                     "/evoscen/commands/bv_cooperative", "/evoscen/commands/sut",
                     "/evoscen/sut/odom", "/evoscen/events", "/evoscen/roster"):
        assert expected in names
    assert columns["/evoscen/world"][:3] == ["id", "role", "policy"]
    assert columns["/evoscen/commands/sut"] == ["id", "throttle", "lane_change"]


@pytest.fixture(scope="module")
def observed(tmp_path_factory):
    """Start the user's observer on a random domain, then a 200-step graph run on that domain."""
    tmp = tmp_path_factory.mktemp("outside")
    topics, columns = topics_page_contract()
    script = tmp / "user_observer.py"
    script.write_text(SUBSCRIBER, encoding="utf-8")
    summary_path, ready = tmp / "summary.json", tmp / "ready"
    (tmp / "config.json").write_text(json.dumps(
        {"topics": [{k: t[k] for k in ("name", "type", "qos")} for t in topics],
         "out": str(summary_path), "ready": str(ready), "timeout_s": 150}))
    from evoscen_bringup.domains import reserve_domain, reserved_by_caller_env

    with reserve_domain(None) as domain_id:  # held until the observer and the graph have ended
        observer = subprocess.Popen([sys.executable, str(script), str(tmp / "config.json")], cwd=tmp,
                                    env=_observer_env(domain_id), text=True,
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        try:
            end = time.monotonic() + 60
            while not ready.exists():
                assert observer.poll() is None, f"observer failed: {observer.communicate()}"
                assert time.monotonic() < end, "observer did not start"
                time.sleep(0.05)
            t0 = time.monotonic()
            run = subprocess.run([sys.executable, "scripts/run_scenario.py", "--mode", "graph", "--steps", str(STEPS),
                                  "--seed", "7", "--domain-id", str(domain_id), "--out", str(tmp / "run"),
                                  "--wait-for", "user_observer"],  # a user's monitor: receives every step
                                 cwd=REPO, env={**os.environ, **reserved_by_caller_env(domain_id)},
                                 capture_output=True, text=True, timeout=150, check=False)
            launcher_s = time.monotonic() - t0
            _out, err = observer.communicate(timeout=60)
        finally:
            if observer.poll() is None:
                observer.kill()
                observer.communicate()
    assert run.returncode == 0, f"graph run failed ({run.returncode}):\n{run.stdout}\n{run.stderr}"
    assert observer.returncode == 0, f"observer failed ({observer.returncode}):\n{err}"
    print(f"\noutside view: launcher {launcher_s:.1f} s; {run.stderr.strip().splitlines()[-1]}")
    return {"summary": json.loads(summary_path.read_text()), "topics": topics, "columns": columns,
            "source": SUBSCRIBER}


def test_observer_is_a_plain_user_node(observed):
    src = observed["source"]
    imports = set(re.findall(r"^\s*(?:import|from)\s+([\w.]+)", src, re.MULTILINE))
    roots = {name.split(".")[0] for name in imports}
    assert roots <= {"importlib", "json", "sys", "time", "numpy", "rclpy"}, roots
    assert "evoscen" not in " ".join(imports)
    assert observed["summary"]["evoscen_imported"] == []
    assert "spin_once" in src


def test_observer_receives_every_step(observed):
    s, topics, columns = observed["summary"], observed["topics"], observed["columns"]
    assert not s["timed_out"], "the observer never saw the run_end event"
    dt_ns = 100_000_000
    counts = {name: v["count"] for name, v in s.items() if isinstance(v, dict) and "count" in v}

    world = s["/evoscen/world"]
    missing = sorted(set(range(STEPS + 1)) - {stamp // dt_ns for stamp in world["stamps"]})
    assert world["count"] == STEPS + 1, (counts, "missing world steps", missing)
    assert sorted(world["stamps"]) == [k * dt_ns for k in range(STEPS + 1)]
    assert world["columns"] == columns["/evoscen/world"]
    assert world["rows"] == [N_VEHICLES] and world["ids"] == list(range(N_VEHICLES)) and world["all_finite"]
    assert world["frame_ids"] == ["map"]
    assert 20 < world["max_speed"] < 40

    clock = s["/clock"]
    assert clock["count"] == STEPS + 1, counts
    assert clock["last_clock_ns"] == STEPS * dt_ns and max(clock["stamps"]) == STEPS * dt_ns

    # the default scenario's BV nodes (by_policy; 20 BVs at 4:3:3 = 8 + 6 + 6), one topic each
    for topic, rows in (("/evoscen/commands/bv_competitive", 8), ("/evoscen/commands/bv_mutual", 6),
                        ("/evoscen/commands/bv_cooperative", 6), ("/evoscen/commands/sut", 1)):
        cmd = s[topic]
        assert cmd["count"] == STEPS, (topic, counts)
        assert sorted(cmd["stamps"]) == [k * dt_ns for k in range(STEPS)], topic
        assert cmd["columns"] == columns[topic] and cmd["rows"] == [rows] and cmd["all_finite"], topic

    odom = s["/evoscen/sut/odom"]
    assert odom["count"] == STEPS + 1, counts
    assert odom["frame_ids"] == ["map"] and odom["child_frame_id"] == "sut/base_link" and odom["unit_quaternion"]
    # the SUT starts at 27 m/s; later it may be slowed by traffic (learned BVs queue at the merge)
    assert 20 < odom["max_odom_speed"] < 40 and 0.0 <= odom["last_speed"] < 40

    roster = s["/evoscen/roster"]
    assert roster["count"] == 1, counts
    assert roster["columns"] == columns["/evoscen/roster"] and roster["rows"] == [N_VEHICLES]

    events = s["/evoscen/events"]
    readme_events = set(re.findall(r"evoscen/\w+", next(t for t in topics if t["name"] == "/evoscen/events")["meaning"]))
    assert "evoscen/run_end" in events["names"] and set(events["names"]) <= readme_events, events["names"]
    assert events["run_end"]["kind"] == "completed" and int(events["run_end"]["step"]) == STEPS
    assert events["count"] == STEPS + 1, counts  # one per step (empty when nothing happened) + run_end

    # every other topic of the table was published and received too
    for t in topics:
        assert s[t["name"]]["count"] >= 1, (t["name"], counts)


def test_late_joiner_gets_latched_roster(observed):
    late, columns = observed["summary"]["late_roster"], observed["columns"]
    assert late["after_world_step"] is not None and late["after_world_step"] >= 5, late
    assert late["count"] == 1, late
    assert late["columns"] == columns["/evoscen/roster"] and late["rows"] == [N_VEHICLES], late
