"""Bounded and validated inputs (issue 16, docs/input-limits.md).

Every bad input below is one stderr line ``error: ...`` and exit status 2 (or an InputError),
never a traceback, never silent acceptance. Bags are made from a short in-process run and
rewritten message by message with one defect each.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

pytestmark = [pytest.mark.e2e, pytest.mark.filterwarnings("ignore::DeprecationWarning")]

REPO = Path(__file__).resolve().parents[1]
STEPS = 30


def script(name: str, *args: object, timeout: float = 120.0) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, f"scripts/{name}", *map(str, args)], cwd=REPO, capture_output=True,
                          text=True, timeout=timeout, check=False)


def one_error_line(res: subprocess.CompletedProcess, *needles: str) -> str:
    assert "Traceback" not in res.stderr, res.stderr
    assert res.returncode == 2, (res.returncode, res.stderr)
    lines = [line for line in res.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), res.stderr
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


# --------------------------------------------------------------------------- config files


@pytest.fixture
def bad_files(tmp_path: Path) -> dict[str, Path]:
    files = {
        "nul": b"name: x\x00y\nsteps: 5\n",
        # 40 nested flow sequences: PyYAML's composer recursed ~1000 deep on such input
        "deep": b"steps: " + b"[" * 2000 + b"]" * 2000 + b"\n",
        "binary": bytes(range(128, 256)) * 4,
        "huge": b"#" * (1 << 20) + b"\nsteps: 5\n",  # 1 MiB of comment + a key: over the 1 MiB limit
    }
    out = {}
    for name, data in files.items():
        out[name] = tmp_path / f"{name}.yaml"
        out[name].write_bytes(data)
    return out


@pytest.mark.parametrize("case, needles", [
    ("nul", ["nul.yaml", "NUL byte at byte 7", "line 1"]),
    ("deep", ["deep.yaml", "deeper than 32 levels"]),
    ("binary", ["binary.yaml", "not UTF-8"]),
    ("huge", ["huge.yaml", f"{(1 << 20) + 10} bytes", "at most 1 MiB"]),
])
def test_bad_config_files_are_one_line(bad_files, tmp_path, case, needles):
    res = script("run_scenario.py", "--mode", "inprocess", "--config", bad_files[case], "--out", tmp_path / "o")
    one_error_line(res, *needles)
    assert not (tmp_path / "o").exists()


def test_dev_zero_config_fails_at_once(tmp_path):
    # /dev/zero is a character device of endless bytes: refused before a byte is read
    res = script("run_scenario.py", "--mode", "inprocess", "--config", "/dev/zero", "--out", tmp_path / "o",
                 timeout=30)
    one_error_line(res, "/dev/zero", "is a device", "expected a regular file")


def test_yaml_alias_chain_is_not_walked_exponentially(tmp_path):
    """30 levels of anchors, each level twice the one below: 2^30 paths, read in well under a second."""
    from evoscen_sim.config.scenario_config import _parse_yaml

    text = "a0: &a0 {x: 1}\n" + "".join(f"a{i}: &a{i} {{p: *a{i - 1}, q: *a{i - 1}}}\n" for i in range(1, 31))
    import time

    t0 = time.perf_counter()
    data, lines = _parse_yaml(text, "aliases.yaml")
    assert time.perf_counter() - t0 < 5
    assert data["a30"]["p"] is data["a29"]
    assert lines["a30"] == 31


# --------------------------------------------------------------------------- numeric limits


@pytest.mark.parametrize("args, needles", [
    (["--steps", "0x10"], ["'steps' = '0x10'", "expected an integer in [1, 1000000]"]),
    (["--steps", "1_6"], ["'steps' = '1_6'"]),
    (["--seed", "0b11"], ["'seed' = '0b11'"]),
    (["--steps", "1000001"], ["'steps' = 1000001", "[1, 1000000]"]),
    (["--steps", "1000000000000"], ["'steps' = 1000000000000"]),
    (["--out", ""], ["--out ''", "non-empty path"]),
    (["--out", "  "], ["--out '  '", "non-empty path"]),
    (["--mode", "graph", "--domain-id", "0x10"], ["--domain-id 0x10", "decimal integer in [0, 232]"]),
    (["--mode", "graph", "--max-misses", "1_0"], ["--max-misses 1_0"]),
])
def test_cli_values_are_strict(tmp_path, args, needles):
    argv = args if "--mode" in args else ["--mode", "inprocess", *args]
    if "--out" not in argv:
        argv += ["--out", tmp_path / "o"]
    res = script("run_scenario.py", *argv)
    one_error_line(res, *needles)
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("dt, ok", [
    (1e-10, False),  # 0.1 ns: every stamp rounds to 0 (the graph then aborted with a deadline error)
    (5e-7, False),  # 500 ns: below the 1 us floor
    (1e-6, True),  # 1000 ns
    (0.0333333333333, False),  # 33333333.3333 ns: the stamps k*33333333 ns would drift from k*dt
    (0.05, True),
    (1.0, True),
    (1.5, False),
])
def test_dt_s_lower_bound_and_whole_nanoseconds(tmp_path, dt, ok):
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sim.errors import InputError

    path = tmp_path / "dt.yaml"
    path.write_text(f"dt_s: {dt!r}\n")
    if ok:
        cfg = load_scenario_config(path)
        assert cfg.dt_s == dt and round(dt * 1e9) >= 1000
    else:
        with pytest.raises(InputError, match=r"'dt_s' = .*\[1e-06, 1\].*whole number of nanoseconds"):
            load_scenario_config(path)


def test_steps_in_the_file_over_the_limit(tmp_path):
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sim.errors import InputError

    path = tmp_path / "s.yaml"
    path.write_text("steps: 1000000000000\n")
    with pytest.raises(InputError, match=r"s.yaml: key 'steps' = 1000000000000: expected an integer in \[1, 1000000\] \(line 1\)"):
        load_scenario_config(path)
    path.write_text("steps: 1000000\n")
    assert load_scenario_config(path).steps == 1_000_000


def test_replay_start_delay_is_bounded(recorded_run):
    res = script("replay.py", recorded_run.bag_dir, "--start-delay", "1e300", timeout=60)
    one_error_line(res, "--start-delay 1e300", "[0, 86400]")
    res = script("replay.py", recorded_run.bag_dir, "--wait-subscribers", "0x1", timeout=60)
    one_error_line(res, "--wait-subscribers 0x1")


# --------------------------------------------------------------------------- training config


@pytest.mark.parametrize("data, extra, needle", [
    (bytes(range(128, 256)), [], "not UTF-8"),
    (b"td3:\n  gamma: 0.9\x00\n", [], "NUL byte"),
    (b"td3: " + b"[" * 3000 + b"]" * 3000, [], "deeper than 32 levels"),
    (b"steps:\n  control: 1000000000000\n", [], "'steps.control' = 1000000000000: expected an integer in [1, 100000000]"),
    (None, ["--steps", "0x10"], "argument --steps"),
    (None, ["--steps", "1_000"], "argument --steps"),
    (None, ["--out", ""], "argument --out: expected a non-empty path"),
])
def test_training_config_and_cli_limits(tmp_path, data, extra, needle):
    argv = ["--stage", "control", "--out", tmp_path / "o"]
    if data is not None:
        (tmp_path / "t.yaml").write_bytes(data)
        argv += ["--config", tmp_path / "t.yaml"]
    if "--out" in extra:
        argv = ["--stage", "control"]
    res = script("train_bv.py", *argv, *extra)
    one_error_line(res, needle)


# --------------------------------------------------------------------------- HighD files


def _highd_dir(tmp_path: Path) -> Path:
    """A tiny valid HighD recording written by evoscen's own writer from an exported run."""
    d = tmp_path / "highd"
    d.mkdir()
    (d / "01_recordingMeta.csv").write_text(
        "id,frameRate,locationId,speedLimit,month,weekDay,startTime,duration,totalDrivenDistance,"
        "totalDrivenTime,numVehicles,numCars,numTrucks,upperLaneMarkings,lowerLaneMarkings\n"
        "1,25,1,-1,1,Mon,00:00,1,1,1,1,1,0,1;4,8;12\n")
    return d


def test_binary_or_device_highd_tracks_are_one_line(tmp_path):
    from evoscen_eval.naturalistic.highd import TRACK_COLUMNS, load_recording_meta, load_tracks
    from evoscen_sim.errors import InputError

    path = tmp_path / "01_tracks.csv"
    path.write_bytes(",".join(TRACK_COLUMNS).encode() + b"\n" + bytes(range(128, 256)) * 64)
    with pytest.raises(InputError, match=r"01_tracks.csv: not UTF-8 text"):
        load_tracks(path)
    dev = tmp_path / "02_tracks.csv"
    dev.symlink_to("/dev/zero")
    with pytest.raises(InputError, match=r"02_tracks.csv: HighD file is a device; expected a regular file"):
        load_tracks(dev)
    meta = _highd_dir(tmp_path) / "01_recordingMeta.csv"
    meta.write_bytes(meta.read_bytes().replace(b"Mon", b"\xff\xfe"))
    with pytest.raises(InputError, match=r"01_recordingMeta.csv: not UTF-8 text"):
        load_recording_meta(meta)


# --------------------------------------------------------------------------- bags


@pytest.fixture(scope="module")
def short_bag(tmp_path_factory) -> Path:
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_sim.config.scenario_config import load_scenario_config

    bag = tmp_path_factory.mktemp("short") / "bag"
    run_inprocess(load_scenario_config(None, {"steps": STEPS, "seed": 3}), bag_dir=bag)
    return bag


def _metadata_records(bag: Path) -> dict[str, dict[str, str]]:
    from mcap.reader import make_reader

    with open(bag / "bag_0.mcap", "rb") as f:
        return {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata() if m.name != "rosbag2"}


def contract_of(bag: Path) -> tuple:
    """The contract rows of ``bag``'s run: its BV nodes' command topics in the bag's order."""
    from evoscen_contract import topics as T
    from evoscen_record.bag_reader import open_bag_reader

    names = dict.fromkeys(T.NODE_BV + topic[len(T.TOPIC_COMMANDS_BV):] for topic, _type, _t, _d in open_bag_reader(bag)
                          if T.is_bv_command_topic(topic))
    return T.contract_for(list(names))


def rewrite_bag(src: Path, dst: Path, transform, topics=None) -> Path:
    """Copy ``src`` to ``dst`` message by message through ``transform(topic, t_ns, data) -> [(topic, t, data)]``."""
    from evoscen_record.bag_reader import open_bag_reader
    from evoscen_record.recorder import BagRecorder

    with BagRecorder(dst, topics or contract_of(src), canonicalize=False, metadata=_metadata_records(src)) as bag:
        for topic, _type, t, data in open_bag_reader(src):
            for out in transform(topic, t, data):
                bag.write(*out)
    return dst


def _world_edit(step: int, vehicle: int, field: str, value: float):
    from evoscen_contract import topics as T
    from evoscen_contract.cdr import TableEncoder, decode_table

    def transform(topic, t, data):
        if topic == T.WORLD.name and t == step * 100_000_000:
            table = decode_table(data)
            arr = np.array(table.data)
            arr[vehicle, table.fields.index(field)] = value
            data = TableEncoder(table.fields, table.frame_id).encode(arr, table.stamp_ns)
        return [(topic, data, t)]
    return transform


def test_nan_in_the_world_table_is_one_line(short_bag, tmp_path):
    bag = rewrite_bag(short_bag, tmp_path / "nan" / "bag", _world_edit(7, 2, "speed", float("nan")))
    from evoscen_contract.cdr import decode_table
    from evoscen_record.bag_reader import open_bag_reader

    vid = next(int(decode_table(d).data[2, decode_table(d).fields.index("id")])
               for topic, _, t, d in open_bag_reader(bag) if topic == "/evoscen/world" and t == 700_000_000)
    res = script("evaluate.py", bag, "--no-plots", "--out", tmp_path / "rep")
    one_error_line(res, str(bag), "'/evoscen/world'", "step 7", "'speed'", f"vehicle {vid}", "nan")
    assert not (tmp_path / "rep").exists()
    res = script("export_highd.py", bag, tmp_path / "hd")
    one_error_line(res, "step 7", "'speed'")
    assert not list((tmp_path).glob("hd/*.csv"))
    inf_bag = rewrite_bag(short_bag, tmp_path / "inf" / "bag", _world_edit(3, 0, "s", float("inf")))
    one_error_line(script("export_highd.py", inf_bag, tmp_path / "hd2"), "step 3", "'s'", "inf")


def test_highd_writer_refuses_non_finite_rows(short_bag, tmp_path):
    from evoscen_eval.naturalistic.fidelity import run_recording
    from evoscen_eval.naturalistic.highd import write_recording
    from evoscen_sim.errors import InputError

    rec = run_recording(short_bag)
    rec.tracks["xVelocity"][5] = np.inf
    with pytest.raises(InputError, match=r"column 'xVelocity' row 6 .* is inf"):
        write_recording(tmp_path / "hd", rec)
    assert not list(tmp_path.glob("hd/*.csv"))


def test_world_topic_of_another_type_is_refused_at_once(short_bag, tmp_path):
    import time
    from dataclasses import replace

    from evoscen_contract import topics as T

    foreign = [replace(s, type_name="sensor_msgs/msg/Imu") if s.name == T.WORLD.name else s
               for s in contract_of(short_bag)]
    bag = rewrite_bag(short_bag, tmp_path / "foreign" / "bag", lambda topic, t, d: [(topic, d, t)], foreign)
    one_error_line(script("evaluate.py", bag, "--no-plots", "--out", tmp_path / "rep"),
                   "'/evoscen/world' is recorded with type 'sensor_msgs/msg/Imu'", "expected 'sensor_msgs/msg/PointCloud2'")
    t0 = time.monotonic()
    res = script("replay.py", bag, "--rate", "0", timeout=60)
    one_error_line(res, "'/evoscen/world' is recorded as 'sensor_msgs/msg/Imu'")
    assert time.monotonic() - t0 < 20  # today: an RCLError traceback after 31 s


def test_a_message_that_does_not_decode_as_its_type_stops_replay_at_once(short_bag, tmp_path):
    from evoscen_contract import topics as T

    def transform(topic, t, data):
        if topic == T.SUT_ODOM.name:  # a nav_msgs/Odometry channel holding 6 bytes
            data = b"\x00\x01\x00\x00\xff\xff"
        return [(topic, data, t)]
    bag = rewrite_bag(short_bag, tmp_path / "undecodable" / "bag", transform)
    res = script("replay.py", bag, "--rate", "0", "--topics", T.SUT_ODOM.name, timeout=60)
    one_error_line(res, "'/evoscen/sut/odom'", "does not decode as its recorded type 'nav_msgs/msg/Odometry'")


def test_duplicated_world_state_is_an_error(short_bag, tmp_path):
    def transform(topic, t, data):
        out = [(topic, data, t)]
        return out * 2 if topic == "/evoscen/world" and t == 1_000_000_000 else out
    bag = rewrite_bag(short_bag, tmp_path / "dup" / "bag", transform)
    one_error_line(script("evaluate.py", bag, "--no-plots", "--out", tmp_path / "rep"),
                   "world state 11 (t = 1000000000 ns) has the same stamp as state 10", "duplicated")


def test_gap_in_world_states_is_a_report_warning(short_bag, tmp_path):
    # states 5..14 dropped (10 missing steps): scored as 21 states, and the report says so
    def transform(topic, t, data):
        return [] if topic == "/evoscen/world" and 500_000_000 <= t < 1_500_000_000 else [(topic, data, t)]
    bag = rewrite_bag(short_bag, tmp_path / "gap" / "bag", transform)
    res = script("evaluate.py", bag, "--no-plots", "--out", tmp_path / "rep")
    assert res.returncode == 0, res.stderr
    report = json.loads((tmp_path / "rep" / "report.json").read_text())
    assert report["run"]["states"] == STEPS + 1 - 10
    gap = [w for w in report["warnings"] if "gap" in w]
    assert len(gap) == 1 and "1 gap in the world states, 10 steps missing" in gap[0], report["warnings"]
    assert "after t = 400000000 ns" in gap[0]
    assert "warning: " in res.stderr and "10 steps missing" in res.stderr


@pytest.mark.parametrize("entry, needle", [
    ("../outside.mcap", "points outside the bag directory"),
    ("/etc/hostname", "points outside the bag directory"),
    ("link.mcap", "resolves outside the bag directory"),
])
def test_relative_file_paths_must_stay_inside_the_bag(short_bag, tmp_path, entry, needle):
    import shutil

    bag = tmp_path / "b" / "bag"
    shutil.copytree(short_bag, bag)
    shutil.copy(bag / "bag_0.mcap", tmp_path / "b" / "outside.mcap")
    (bag / "link.mcap").symlink_to(tmp_path / "b" / "outside.mcap")
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())
    meta["rosbag2_bagfile_information"]["relative_file_paths"] = [entry]
    (bag / "metadata.yaml").write_text(yaml.safe_dump(meta))
    for tool, args in (("evaluate.py", ["--no-plots", "--out", tmp_path / "rep"]),
                       ("replay.py", ["--rate", "0"]), ("export_highd.py", [tmp_path / "hd"])):
        one_error_line(script(tool, bag, *args, timeout=60), f"relative_file_paths entry {entry!r}", needle)


@pytest.mark.parametrize("data, needle", [
    (b"rosbag2_bagfile_information:\n  version: \xff\xfe\n", "not UTF-8"),
    (b"rosbag2_bagfile_information: {version: 9}\x00\n", "NUL byte"),
    (b"a: " + b"[" * 2000 + b"]" * 2000, "deeper than 32 levels"),
])
def test_bad_metadata_yaml_is_one_line(short_bag, tmp_path, data, needle):
    import shutil

    bag = tmp_path / "bag"
    shutil.copytree(short_bag, bag)
    (bag / "metadata.yaml").write_bytes(data)
    for tool, args in (("evaluate.py", ["--no-plots", "--out", tmp_path / "rep"]),
                       ("replay.py", ["--rate", "0"]), ("export_highd.py", [tmp_path / "hd"])):
        one_error_line(script(tool, bag, *args, timeout=60), "metadata.yaml", needle)


# --------------------------------------------------------------------------- determinism


def test_bag_holds_no_machine_specific_path(short_bag):
    """The scenario record names the map by file name (+ SHA-256 of its bytes), not by where it lies."""
    import hashlib

    from evoscen_sim.config.scenario_config import share_path

    record = _metadata_records(short_bag)["evoscen"]
    scenario = yaml.safe_load(record["scenario_yaml"])
    assert scenario["map"] == "onramp.xodr"
    assert record["map_sha256"] == hashlib.sha256(share_path("maps/onramp.xodr").read_bytes()).hexdigest()
    blob = (short_bag / "bag_0.mcap").read_bytes() + (short_bag / "metadata.yaml").read_bytes()
    for where in {str(REPO), str(share_path("maps/onramp.xodr").parent), os.getcwd()}:
        assert where.encode() not in blob, where


def test_same_run_from_another_map_location_is_byte_identical(tmp_path):
    """One config, its map copied to two different directories: the bags are byte-identical."""
    import shutil

    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_sim.config.scenario_config import load_scenario_config, share_path

    blobs = []
    for where in ("one/place", "another/much/deeper/place"):
        d = tmp_path / where
        d.mkdir(parents=True)
        shutil.copy(share_path("maps/onramp.xodr"), d / "onramp.xodr")
        (d / "s.yaml").write_text("map: onramp.xodr\nsteps: 10\nbvs: {count: 3}\nspawn: {ramp_vehicles: 1}\n")
        cfg = load_scenario_config(d / "s.yaml")
        assert cfg.map == str((d / "onramp.xodr").resolve())
        run_inprocess(cfg, bag_dir=d / "bag")
        blobs.append(((d / "bag" / "bag_0.mcap").read_bytes(), (d / "bag" / "metadata.yaml").read_bytes()))
    assert blobs[0] == blobs[1]


def test_no_bvs_means_no_bv_command_messages(tmp_path):
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_record.bag_reader import open_bag_reader
    from evoscen_sim.config.scenario_config import load_scenario_config

    cfg = load_scenario_config(None, {"steps": 20, "bvs.count": 0, "spawn.ramp_vehicles": 0})
    run_inprocess(cfg, bag_dir=tmp_path / "bag")
    topics = [t for t, *_ in open_bag_reader(tmp_path / "bag")]
    assert topics.count("/evoscen/commands/bv") == 0
    assert topics.count("/evoscen/commands/sut") == 20
    meta = yaml.safe_load((tmp_path / "bag" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    counts = {e["topic_metadata"]["name"]: e["message_count"] for e in meta["topics_with_message_count"]}
    assert counts["/evoscen/commands/bv"] == 0  # the topic is declared, as in the graph's bag
    assert re.fullmatch(r"[0-9a-f]{64}", _metadata_records(tmp_path / "bag")["evoscen"]["map_sha256"])
