"""End-to-end tests of ``scripts/replay.py``: a recorded bag comes back on the wire, byte for byte.

A 50-step in-process run is recorded once (``run_scenario.py --mode inprocess --steps 50``).
Each wire test starts two real processes on a ROS_DOMAIN_ID reserved on the host for this module
(``evoscen_bringup.domains``, as the launcher reserves its own: a replay publishes
``/evoscen/world`` and must never land on a running graph's domain) with localhost-only
discovery: a raw subscriber (``probe.py``, written below into ``tmp_path``:
``raw=True`` subscriptions with the bag's QoS (metadata.yaml) on every topic of the bag; it saves the
received bytes per topic, in arrival order, and the QoS of the publishers it sees) and the
replay with ``--wait-subscribers 1`` so that no first message is lost. Expectations are the
bag's own bytes (read with ``open_bag_reader``): the recorded CDR is already padded to a
multiple of 4 bytes (``evoscen_contract.cdr.pad4``), as DDS transports it, so it must come back
identical. Order is checked per topic (DDS orders samples per writer, not across topics).
"""

from __future__ import annotations

import json
import os
import pickle
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
import yaml

from evoscen_record.bag_reader import open_bag_reader

REPO = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.e2e
REPLAY = "scripts/replay.py"
STEPS = 50
#: Seconds a probe waits for its messages before giving up.
PROBE_TIMEOUT_S = 20.0

PROBE = textwrap.dedent('''
    """Raw subscriber: python probe.py SPEC.json OUT.pickle (see tests/test_replay.py)."""
    import importlib, json, pickle, sys, time

    import rclpy
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    spec = json.load(open(sys.argv[1]))
    rclpy.init()
    node = rclpy.create_node("replay_probe", enable_rosout=False, start_parameter_services=False)
    got = {t["name"]: [] for t in spec["topics"]}
    pub_qos = {}
    subs = []
    for t in spec["topics"]:
        pkg, _, cls = t["type"].split("/")
        msg_class = getattr(importlib.import_module(pkg + ".msg"), cls)
        qos = QoSProfile(
            history=HistoryPolicy.KEEP_ALL if t["history"] == "keep_all" else HistoryPolicy.KEEP_LAST,
            depth=max(t["depth"], 1),
            reliability=ReliabilityPolicy.RELIABLE if t["reliability"] == "reliable" else ReliabilityPolicy.BEST_EFFORT,
            durability=DurabilityPolicy.TRANSIENT_LOCAL if t["durability"] == "transient_local" else DurabilityPolicy.VOLATILE)

        def callback(data, name=t["name"]):
            got[name].append(bytes(data))

        subs.append(node.create_subscription(msg_class, t["name"], callback, qos, raw=True))
    expected = spec["expected"]
    deadline = time.monotonic() + spec["timeout_s"]
    done_at = None
    while time.monotonic() < deadline or (done_at is not None and len(pub_qos) < len(expected)
                                           and time.monotonic() < done_at + 2.0):
        rclpy.spin_once(node, timeout_sec=0.02)
        for name in got:  # note the QoS the replay's publishers offer, while they are alive
            if got[name] and name not in pub_qos:
                infos = [(i.node_name, i.qos_profile.reliability.name.lower(), i.qos_profile.durability.name.lower())
                         for i in node.get_publishers_info_by_topic(name)]
                if infos:
                    pub_qos[name] = infos
        if done_at is None and all(len(got[n]) >= c for n, c in expected.items()):
            done_at = time.monotonic()
            deadline = min(deadline, done_at + spec["linger_s"])  # catch extra messages
    with open(sys.argv[2], "wb") as f:
        pickle.dump({"messages": got, "publisher_qos": pub_qos, "complete": done_at is not None}, f)
    node.destroy_node()
    rclpy.shutdown()
''')


@pytest.fixture(scope="module")
def domain():
    """This module's ROS_DOMAIN_ID, reserved on the host while its tests run (one at a time)."""
    from evoscen_bringup.domains import reserve_domain

    with reserve_domain(None) as reserved:
        yield reserved


def _env(domain: int) -> dict[str, str]:
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(domain)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("ROS_LOCALHOST_ONLY", None)
    env["PYTHONUNBUFFERED"] = "1"
    return env


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 50-step in-process run's bag."""
    out = tmp_path_factory.mktemp("replay") / "run"
    proc = subprocess.run([sys.executable, "scripts/run_scenario.py", "--mode", "inprocess", "--steps", str(STEPS),
                           "--out", str(out), "--quiet"], cwd=REPO, capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr
    return out / "bag"


@pytest.fixture(scope="module")
def bag_topics(bag: Path) -> dict[str, dict]:
    """``{topic: {"type", "history", "depth", "reliability", "durability"}}`` from the bag's metadata.yaml."""
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    out = {}
    for entry in info["topics_with_message_count"]:
        md = entry["topic_metadata"]
        (qos,) = md["offered_qos_profiles"]
        out[md["name"]] = {"type": md["type"], **{k: qos[k] for k in ("history", "depth", "reliability", "durability")}}
    return out


@pytest.fixture(scope="module")
def recorded(bag: Path) -> dict[str, list[bytes]]:
    """``{topic: [cdr bytes in log-time order]}`` of the bag, every topic (also empty ones)."""
    out: dict[str, list[bytes]] = {}
    for topic, _type, _t, data in open_bag_reader(bag, log_time_order=True):
        out.setdefault(topic, []).append(data)
    return out


def _start_probe(tmp_path: Path, domain: int, topics: dict[str, dict], expected: dict[str, int],
                 linger_s: float = 0.3) -> tuple:
    """Start the raw subscriber on every topic of the bag (its QoS); returns (process, result path)."""
    script = tmp_path / "probe.py"
    script.write_text(PROBE)
    spec = {"topics": [{"name": name, **t} for name, t in topics.items()],
            "expected": expected, "timeout_s": PROBE_TIMEOUT_S, "linger_s": linger_s}
    (tmp_path / "probe.json").write_text(json.dumps(spec))
    result = tmp_path / "probe.pickle"
    proc = subprocess.Popen([sys.executable, str(script), str(tmp_path / "probe.json"), str(result)],
                            cwd=REPO, env=_env(domain), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    return proc, result


def _finish_probe(proc: subprocess.Popen, result: Path) -> dict:
    _out, err = proc.communicate(timeout=PROBE_TIMEOUT_S + 15)
    assert proc.returncode == 0, f"probe failed: {err}"
    with result.open("rb") as f:
        return pickle.load(f)


def _replay(bag: Path, *args: str, domain: int, timeout: float = 60) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, REPLAY, str(bag), *args, "--domain-id", str(domain)], cwd=REPO,
                          env=_env(domain), capture_output=True, text=True, timeout=timeout, check=False)


def _summary(stdout: str) -> dict[str, float]:
    m = re.search(r"^replayed: (\d+) messages on (\d+) topics?, (\d+) pass(?:es)?, simulated ([0-9.]+) s, "
                  r"wall ([0-9.]+) s$", stdout, re.M)
    assert m, stdout
    return dict(zip(("messages", "topics", "passes", "sim_s", "wall_s"), map(float, m.groups())))


# ------------------------------------------------------------------ on the wire


def test_replay_delivers_the_recorded_bytes_in_order(bag: Path, bag_topics, recorded, tmp_path: Path, domain: int) -> None:
    expected = {topic: len(msgs) for topic, msgs in recorded.items()}
    probe, result = _start_probe(tmp_path, domain, bag_topics, expected)
    rep = _replay(bag, "--rate", "0", "--wait-subscribers", "1", domain=domain)
    got = _finish_probe(probe, result)
    assert rep.returncode == 0, rep.stderr
    assert got["complete"], {t: len(m) for t, m in got["messages"].items()}
    for topic in bag_topics:
        assert got["messages"][topic] == recorded.get(topic, []), topic  # same bytes, same order, nothing extra
    summary = _summary(rep.stdout)
    assert summary["messages"] == sum(expected.values()) and summary["topics"] == len(bag_topics)
    assert summary["sim_s"] == pytest.approx(STEPS * 0.1)
    # the publishers offer the recorded (= contract) QoS
    for topic in recorded:
        # (the node name may still be unknown to the probe's graph cache; the replay is the only publisher)
        offered = {(rel, dur) for _node, rel, dur in got["publisher_qos"][topic]}
        assert offered == {(bag_topics[topic]["reliability"], bag_topics[topic]["durability"])}, topic


def test_topics_filter_and_rate_pacing(bag: Path, bag_topics, recorded, tmp_path: Path, domain: int) -> None:
    chosen = ["/clock", "/evoscen/world"]
    probe, result = _start_probe(tmp_path, domain, bag_topics, {t: len(recorded[t]) for t in chosen}, linger_s=0.5)
    t0 = time.monotonic()
    rep = _replay(bag, "--rate", "10", "--wait-subscribers", "1", "--topics", *chosen, domain=domain)
    elapsed = time.monotonic() - t0
    got = _finish_probe(probe, result)
    assert rep.returncode == 0, rep.stderr
    assert got["complete"]
    for topic in chosen:
        assert got["messages"][topic] == recorded[topic], topic
    for topic in set(bag_topics) - set(chosen):
        assert got["messages"][topic] == [], topic
    summary = _summary(rep.stdout)
    assert summary["topics"] == 2 and summary["messages"] == len(recorded["/clock"]) + len(recorded["/evoscen/world"])
    # 5 s of simulation at 10x: 0.5 s of publishing (loose bounds: it is paced, and faster than real time)
    assert 0.4 <= summary["wall_s"] < 4.0
    assert elapsed >= 0.4


def test_loop_repeats_until_ctrl_c(bag: Path, bag_topics, recorded, tmp_path: Path, domain: int) -> None:
    clock = recorded["/clock"]
    probe, result = _start_probe(tmp_path, domain, bag_topics, {"/clock": 2 * len(clock)}, linger_s=0.0)
    rep = subprocess.Popen([sys.executable, REPLAY, str(bag), "--rate", "20", "--loop", "--topics", "/clock",
                            "--wait-subscribers", "1", "--domain-id", str(domain)],
                           cwd=REPO, env=_env(domain), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        got = _finish_probe(probe, result)
        assert rep.poll() is None, "a looping replay ended by itself"
        rep.send_signal(signal.SIGINT)
        out, err = rep.communicate(timeout=15)
    finally:
        if rep.poll() is None:
            rep.kill()
    assert got["complete"]
    assert got["messages"]["/clock"][: 2 * len(clock)] == clock + clock
    assert rep.returncode == 130, (rep.returncode, out, err)
    assert re.search(r"^interrupted: \d+ messages sent, [2-9]\d* full passes", out, re.M), out
    assert "Traceback" not in err


# ------------------------------------------------------------------ bad input


def _write_foreign_bag(path: Path) -> Path:
    """A rosbag2 MCAP bag whose one topic has a type that is not installed."""
    from mcap.writer import Writer

    path.mkdir()
    with (path / "foreign.mcap").open("wb") as f:
        w = Writer(f)
        w.start(profile="ros2", library="test")
        sid = w.register_schema(name="nonexistent_pkg/msg/Foo", encoding="ros2msg", data=b"int32 x")
        cid = w.register_channel(topic="/foo", message_encoding="cdr", schema_id=sid,
                                 metadata={"offered_qos_profiles": ""})
        w.add_message(channel_id=cid, log_time=1, publish_time=1, data=b"\x00\x01\x00\x00\x07\x00\x00\x00")
        w.finish()
    return path


def _run_in_process(argv: list[str]) -> tuple[int, str, str]:
    """``scripts/replay.py`` ``main(argv)`` in this process (for input that fails before the middleware starts)."""
    import contextlib
    import importlib.util
    import io

    sys.path.insert(0, str(REPO / "scripts"))
    try:
        spec = importlib.util.spec_from_file_location("evoscen_replay_cli", REPO / REPLAY)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(REPO / "scripts"))
    handlers = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    env = dict(os.environ)
    out, err = io.StringIO(), io.StringIO()
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = module.main(argv)
    finally:
        for sig, handler in handlers.items():
            signal.signal(sig, handler)
        os.environ.clear()
        os.environ.update(env)
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def error_runs(bag: Path, tmp_path_factory: pytest.TempPathFactory, domain: int) -> dict[str, tuple]:
    """Every bad-input case: ``{case: (args, returncode, stdout, stderr)}``.

    Cases ending in ``_process`` run as real processes (exit status as a user sees it, and the
    no-subscriber timeout, which starts the middleware), concurrently; the rest fail before the
    middleware starts and run in this process (``main(argv)``), to keep the file fast.
    """
    base = tmp_path_factory.mktemp("replay_errors")
    corrupt = base / "corrupt"
    corrupt.mkdir()
    (corrupt / "metadata.yaml").write_text((bag / "metadata.yaml").read_text())
    (corrupt / "bag_0.mcap").write_bytes(b"\x89MCAP0\r\n" + os.urandom(200))
    truncated = base / "truncated"
    truncated.mkdir()
    (truncated / "metadata.yaml").write_text((bag / "metadata.yaml").read_text())
    (truncated / "bag_0.mcap").write_bytes((bag / "bag_0.mcap").read_bytes()[:3000])
    empty = base / "empty"
    empty.mkdir()
    cases = {
        "missing": [str(base / "nope")],
        "missing_process": [str(base / "nope")],
        "empty_dir": [str(empty)],
        "corrupt": [str(corrupt)],
        "truncated": [str(truncated)],
        "rate_negative": [str(bag), "--rate", "-1"],
        "rate_text_process": [str(bag), "--rate", "fast"],
        "rate_nan": [str(bag), "--rate", "nan"],
        "start_delay": [str(bag), "--start-delay", "-2"],
        "domain": [str(bag), "--domain-id", "500"],
        "unknown_topic": [str(bag), "--topics", "/clock", "/not/there"],
        "type_not_installed": [str(_write_foreign_bag(base / "foreign"))],
        "no_subscribers_process": [str(bag), "--topics", "/clock", "--wait-subscribers", "1",
                                   "--wait-timeout", "0.5", "--domain-id", str(domain)],
        "nobody_listening_process": [str(bag), "--rate", "0", "--wait-timeout", "0.5", "--domain-id", str(domain)],
    }
    procs = {name: subprocess.Popen([sys.executable, REPLAY, *args], cwd=REPO, env=_env(domain), text=True,
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE)
             for name, args in cases.items() if name.endswith("_process")}
    out = {name: (args, *_run_in_process(args)) for name, args in cases.items() if name not in procs}
    for name, proc in procs.items():
        stdout, stderr = proc.communicate(timeout=60)
        out[name] = (cases[name], proc.returncode, stdout, stderr)
    return out


@pytest.mark.parametrize("case, needles", [
    ("missing", ["nope", "no such bag"]),
    ("missing_process", ["nope", "no such bag"]),
    ("empty_dir", ["empty", "expected exactly one"]),
    ("corrupt", ["corrupt", "bag_0.mcap"]),
    ("truncated", ["truncated", "bag_0.mcap"]),
    ("rate_negative", ["--rate -1", ">= 0"]),
    ("rate_text_process", ["--rate fast"]),
    ("rate_nan", ["--rate nan"]),
    ("start_delay", ["--start-delay -2"]),
    ("domain", ["--domain-id 500"]),
    ("unknown_topic", ["--topics /not/there", "/clock, /evoscen/world", "/evoscen/roster"]),
    ("type_not_installed", ["'/foo'", "nonexistent_pkg/msg/Foo", "not installed"]),
])
def test_bad_input_is_one_error_line_and_status_2(error_runs, case, needles) -> None:
    args, code, stdout, stderr = error_runs[case]
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert code == 2, (args, stderr)
    assert len(lines) == 1 and lines[0].startswith("error: "), stderr
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    assert stdout == ""


def test_no_subscribers_within_the_timeout_is_status_1(error_runs) -> None:
    _args, code, stdout, stderr = error_runs["no_subscribers_process"]
    assert code == 1, stderr
    assert re.search(r"^error: --wait-subscribers 1: after 0.5 s .*fewer subscribers on /clock$", stderr, re.M), stderr
    assert "replayed" not in stdout


def test_a_replay_nobody_received_is_status_1(error_runs, recorded) -> None:
    """No subscriber on the domain: every message went to nobody - one error line saying so, status 1
    (docs/architecture.md §7), after the usual summary."""
    _args, code, stdout, stderr = error_runs["nobody_listening_process"]
    assert code == 1, stderr
    topics = [t for t, msgs in recorded.items() if msgs]
    sent = sum(len(recorded[t]) for t in topics)
    assert _summary(stdout)["messages"] == sent
    errors = [line for line in stderr.splitlines() if line.startswith(("error:", "warning:"))]
    assert errors == [f"error: no subscriber matched any of the {len(topics)} topics while they were replayed: the "
                      f"{sent} messages reached nobody; start the receiving node first (same ROS_DOMAIN_ID and "
                      "discovery range) or pass --wait-subscribers 1"], stderr


def test_topics_nobody_received_are_a_warning(capsys) -> None:
    """Some topics without a subscriber (a viewer that reads a few): one warning naming them, status 0."""
    from evoscen_eval.scenes import replay_wire as module

    assert module.unheard_status(["/clock", "/evoscen/events", "/evoscen/world"], {"/evoscen/world"}, 30) == 0
    assert capsys.readouterr().err == ("warning: no subscriber matched /clock, /evoscen/events while they were "
                                       "replayed: their messages reached nobody\n")
    assert module.unheard_status(["/clock"], {"/clock"}, 10) == 0 and capsys.readouterr().err == ""
