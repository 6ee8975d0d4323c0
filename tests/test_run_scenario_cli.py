"""End-to-end tests of ``scripts/run_scenario.py``: bad inputs, a successful run, overrides,
determinism and ``--no-record``.

Bad input must give exit status 2 and exactly one stderr line ``error: ...`` that names the
offending file / key / value (docs/CONVENTIONS.md), never a traceback.
"""

from __future__ import annotations

import json
import re
from collections import Counter
from pathlib import Path

import pytest
import yaml

pytestmark = [pytest.mark.e2e, pytest.mark.filterwarnings("ignore::DeprecationWarning")]  # mcap_ros2.reader import

# --------------------------------------------------------------------------- helpers


def assert_one_line_error(res, *needles: str) -> str:
    """Exit 2, no traceback, stderr = one line ``error: ...`` containing every needle."""
    assert "Traceback" not in res.stderr, res.stderr
    assert res.returncode == 2, (res.returncode, res.stderr)
    lines = res.stderr_lines()
    assert len(lines) == 1, f"expected one stderr line, got {len(lines)}: {res.stderr!r}"
    line = lines[0]
    assert line.startswith("error: "), line
    assert res.stderr.endswith("\n") and res.stderr.count("\n") == 1, repr(res.stderr)
    for needle in needles:
        assert needle in line, f"{needle!r} not in {line!r}"
    assert "bag:" not in res.stdout
    return line


def line_of(text: str, needle: str) -> int:
    """1-based number of the first line of ``text`` containing ``needle``."""
    for i, line in enumerate(text.splitlines(), start=1):
        if needle in line:
            return i
    raise AssertionError(f"{needle!r} not found")


def _read_bag_topics(bag_dir: Path) -> dict[str, int]:
    meta = yaml.safe_load((bag_dir / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    return {t["topic_metadata"]["name"]: t["message_count"] for t in meta["topics_with_message_count"]}


@pytest.fixture
def truncated_xodr(tmp_path: Path, map_source: Path) -> tuple[Path, int]:
    """The shipped map cut off in the middle of the ``<arc .../>`` tag; (path, line of the cut)."""
    text = map_source.read_text(encoding="utf-8")
    cut_line = line_of(text, "<arc curvature=")
    lines = text.splitlines(keepends=True)
    partial = lines[cut_line - 1]
    partial = partial[: partial.index("curvature=") + len("curv")]
    path = tmp_path / "truncated.xodr"
    path.write_text("".join(lines[: cut_line - 1]) + partial, encoding="utf-8")
    return path, cut_line


@pytest.fixture
def spiral_xodr(tmp_path: Path, map_source: Path) -> tuple[Path, int]:
    """The shipped map with its arc replaced by an (unsupported) ``<spiral>``; (path, its line)."""
    text = map_source.read_text(encoding="utf-8")
    assert text.count('<arc curvature="0.0005"/>') == 1
    text = text.replace('<arc curvature="0.0005"/>', '<spiral curvStart="0" curvEnd="0.0005"/>')
    path = tmp_path / "spiral.xodr"
    path.write_text(text, encoding="utf-8")
    return path, line_of(text, "<spiral ")


def write_config(tmp_path: Path, text: str, name: str = "scenario.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


# --------------------------------------------------------------------------- bad inputs


def test_truncated_xodr_names_file_and_line(cli, tmp_path, truncated_xodr):
    xodr, line = truncated_xodr
    cfg = write_config(tmp_path, f"map: {xodr.name}\n")  # relative to the config file
    out = tmp_path / "out"
    res = cli("--config", cfg, "--steps", 10, "--out", out, "--quiet")
    msg = assert_one_line_error(res, f"{xodr}:{line}:", "not well-formed XML")
    assert "error: " + str(xodr) in msg
    assert not (out / "bag").exists()


def test_spiral_geometry_names_file_line_and_element(cli, tmp_path, spiral_xodr):
    xodr, line = spiral_xodr
    cfg = write_config(tmp_path, f"map: {xodr}\n")  # absolute path
    out = tmp_path / "out"
    res = cli("--config", cfg, "--steps", 10, "--out", out, "--quiet")
    assert_one_line_error(res, f"{xodr}:{line}:", "spiral", "line, arc")
    assert not (out / "bag").exists()


def test_malformed_xodr_without_quiet_is_still_one_line(cli, tmp_path, truncated_xodr):
    xodr, line = truncated_xodr
    cfg = write_config(tmp_path, f"map: {xodr.name}\n")
    res = cli("--config", cfg, "--steps", 10, "--out", tmp_path / "out")  # no --quiet
    assert_one_line_error(res, f"{xodr}:{line}:")


@pytest.mark.parametrize(
    ("text", "key", "value", "yaml_line"),
    [
        ('name: typed\nsteps: "ten"\n', "'steps'", "'ten'", 2),
        ("bvs:\n  count: true\n", "'bvs.count'", "True", 2),
    ],
    ids=["steps-str", "bvs.count-bool"],
)
def test_config_wrong_type_names_file_and_key(cli, tmp_path, text, key, value, yaml_line):
    cfg = write_config(tmp_path, text, "typed.yaml")
    out = tmp_path / "out"
    # no --steps override: it would replace the bad 'steps'
    res = cli("--config", cfg, "--out", out, "--quiet")
    msg = assert_one_line_error(res, str(cfg), key, value, "expected an integer", f"(line {yaml_line})")
    assert msg.startswith(f"error: {cfg}: ")
    assert not out.exists()  # validation happens before anything is written


def test_unknown_sut_lists_choices(cli, tmp_path):
    res = cli("--sut", "nosuch", "--steps", 10, "--out", tmp_path / "out", "--quiet")
    assert_one_line_error(res, "'sut.model'", "'nosuch'", "expected one of", "level0", "command line")


def test_negative_steps_names_steps(cli, tmp_path):
    res = cli("--steps", -5, "--out", tmp_path / "out", "--quiet")
    assert_one_line_error(res, "'steps'", "-5", "[1, 1000000]", "command line")


def test_output_below_regular_file_names_directory(cli, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory\n")
    out = blocker / "out"
    res = cli("--steps", 10, "--out", out, "--quiet")
    assert_one_line_error(res, str(out), "cannot write the output directory")
    assert blocker.read_text() == "not a directory\n"


@pytest.mark.parametrize("overwrite", [False, True], ids=["plain", "overwrite"])
def test_bag_path_is_a_regular_file(cli, tmp_path, overwrite):
    out = tmp_path / "out"
    out.mkdir()
    (out / "bag").write_text("x")
    res = cli("--steps", 5, "--out", out, "--quiet", *(["--overwrite"] if overwrite else []))
    assert_one_line_error(res, str(out / "bag"))


def test_existing_bag_needs_overwrite(cli, tmp_path):
    out = tmp_path / "out"
    first = cli("--steps", 5, "--seed", 1, "--out", out, "--quiet")
    assert first.returncode == 0, first.stderr
    bag = out / "bag"
    before = {p.name: p.read_bytes() for p in bag.iterdir()}
    assert set(before) == {"metadata.yaml", "bag_0.mcap"}

    refused = cli("--steps", 7, "--seed", 1, "--out", out, "--quiet")
    assert_one_line_error(refused, str(bag), "--overwrite")
    assert {p.name: p.read_bytes() for p in bag.iterdir()} == before  # untouched

    replaced = cli("--steps", 7, "--seed", 1, "--out", out, "--quiet", "--overwrite")
    assert replaced.returncode == 0, replaced.stderr
    # 7 steps is less than one complexity window: the report says so, nothing else is on stderr
    assert replaced.stderr == "warning: 8 states is shorter than one complexity window (100 states): no complexity score\n"
    assert sorted(p.name for p in bag.iterdir()) == ["bag_0.mcap", "metadata.yaml"]
    counts = _read_bag_topics(bag)
    assert counts["/clock"] == 8 and counts["/evoscen/commands/bv_mutual"] == 7  # the new run's, not 6/5


def test_overwrite_keeps_old_bag_when_input_is_bad(cli, tmp_path, truncated_xodr):
    out = tmp_path / "out"
    (out / "bag").mkdir(parents=True)
    (out / "bag" / "metadata.yaml").write_text("previous run\n")  # stands for an earlier bag
    before = {p.name: p.read_bytes() for p in (out / "bag").iterdir()}
    xodr, line = truncated_xodr
    cfg = write_config(tmp_path, f"map: {xodr.name}\n")
    res = cli("--config", cfg, "--steps", 5, "--out", out, "--quiet", "--overwrite")
    assert_one_line_error(res, f"{xodr}:{line}:")
    assert (out / "bag").is_dir()
    assert {p.name: p.read_bytes() for p in (out / "bag").iterdir()} == before


# --------------------------------------------------------------------------- success


def test_successful_run_outputs(recorded_run):
    res, out = recorded_run.result, recorded_run.out
    assert res.returncode == 0
    assert res.stderr == ""  # --quiet: no progress bar
    summary = recorded_run.summary
    assert summary["steps"] == recorded_run.steps
    assert summary["sim_time_s"] == pytest.approx(recorded_run.steps * 0.1)
    assert Path(summary["bag"]).resolve() == (out / "bag").resolve()
    assert sorted(p.name for p in out.iterdir()) == ["bag", "report", "scenario.yaml"]
    names = {p.name for p in (out / "report").iterdir()}
    assert {"report.json", "report.md", "speed.png", "timeline.png", "traffic.png", "ttc.png"} <= names
    report = json.loads((out / "report" / "report.json").read_text())
    # plus a snapshot at the worst exposure (if any) and at each SUT collision (numbered)
    extra = names - {"report.json", "report.md", "speed.png", "timeline.png", "traffic.png", "ttc.png", "run.gif"}
    assert "run.gif" in names  # the bird's-eye animation
    assert ("worst_exposure.png" in extra) == bool(report["safety"]["exposures"]), extra
    assert all(re.fullmatch(r"collision_\d+\.png", n) for n in extra - {"worst_exposure.png"}), extra
    # weight × score per term (the effective weights: 0.75/0.25 when interaction is undefined, evaluation.md §4)
    # D first, then the method's I (weight × score per term), then the scenario's K and the SUT's counts
    lines = res.stdout.splitlines()
    at = next(n for n, line in enumerate(lines) if line.startswith("D, the comparative score: "))
    assert re.fullmatch(r"D, the comparative score: [0-9.]+ = P·\(0\.6·S \+ 0\.2·L \+ 0\.2·X\): progress P [0-9.]+, "
                        r"safety per SUT-km S [0-9.]+, lane-change time L [0-9.]+, interaction X [0-9.]+", lines[at])
    assert re.fullmatch(r"the method's intelligence I \(for reproducing the paper\): [0-9.]+ = [0-9.]+ × safety I_s "
                        r"[0-9.]+ \+ [0-9.]+ × efficiency I_e [0-9.]+ \+ "
                        r"([0-9.]+ × interaction I_i [0-9.]+|interaction I_i undefined \(left out\))", lines[at + 1])
    assert re.fullmatch(r"complexity K \(the scenario's\): [0-9.]+  SUT collisions: \d+  SUT exposures: \d+",
                        lines[at + 2]), res.stdout
    assert f"report: {out / 'report' / 'report.md'}" in res.stdout
    assert sorted(p.name for p in (out / "bag").iterdir()) == ["bag_0.mcap", "metadata.yaml"]
    assert (out / "bag" / "bag_0.mcap").stat().st_size > 0

    meta = yaml.safe_load((out / "bag" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["storage_identifier"] == "mcap"
    assert meta["relative_file_paths"] == ["bag_0.mcap"]
    assert meta["message_count"] == summary["messages"]
    assert meta["starting_time"]["nanoseconds_since_epoch"] == 0
    assert meta["duration"]["nanoseconds"] == recorded_run.steps * 100_000_000

    # scenario.yaml: the resolved config, with the command-line overrides applied
    from evoscen_sim.config.scenario_config import load_scenario_config

    cfg = load_scenario_config(out / "scenario.yaml")
    assert (cfg.steps, cfg.seed) == (recorded_run.steps, recorded_run.seed)
    assert Path(cfg.map).is_absolute() and Path(cfg.map).name == "onramp.xodr"


def test_progress_bar_goes_to_stderr_not_stdout(cli, tmp_path, summary_of):
    res = cli("--steps", 20, "--out", tmp_path / "out")  # no --quiet
    assert res.returncode == 0, res.stderr
    assert "step" in res.stderr  # the tqdm bar
    assert summary_of(res.stdout)["steps"] == 20
    assert "%" not in res.stdout


def _bag_bytes(out: Path) -> tuple[bytes, bytes]:
    return (out / "bag" / "bag_0.mcap").read_bytes(), (out / "bag" / "metadata.yaml").read_bytes()


def test_explicit_config_and_scenario_yaml_reproduce_the_run(cli, cli_concurrently, tmp_path):
    """``--config`` with the shipped file gives the same bag as no ``--config``, and the written
    scenario.yaml is complete: running it again gives the same bag too.

    (The runs are made together, not compared with the session run, so that a concurrent
    rebuild of the workspace cannot make them differ.)
    """
    from evoscen_sim.config.scenario_config import share_path

    a, b, c = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    runs = [cli("--steps", 100, "--seed", 5, "--out", a, "--quiet")]
    runs += cli_concurrently(
        ["--config", share_path("config/default_scenario.yaml"), "--steps", 100, "--seed", 5,
         "--out", b, "--quiet"],
        ["--config", a / "scenario.yaml", "--out", c, "--quiet"],
    )
    for res in runs:
        assert res.returncode == 0, res.stderr
    assert _bag_bytes(a) == _bag_bytes(b) == _bag_bytes(c)
    assert (a / "scenario.yaml").read_bytes() == (b / "scenario.yaml").read_bytes() == (c / "scenario.yaml").read_bytes()


def test_overrides_bvs_mix_sut(cli, tmp_path, summary_of):
    import numpy as np
    from evoscen_contract import topics as T
    from evoscen_contract.tables import table_columns
    from evoscen_sim.config.scenario_config import load_scenario_config
    from mcap_ros2.reader import read_ros2_messages

    out = tmp_path / "out"
    steps = 20
    res = cli("--mode", "inprocess", "--steps", steps, "--seed", 3, "--bvs", 5, "--mix", "1:1:1",
              "--sut", "level0", "--out", out, "--quiet")
    assert res.returncode == 0, res.stderr
    assert summary_of(res.stdout)["steps"] == steps

    cfg = load_scenario_config(out / "scenario.yaml")
    assert cfg.bvs.count == 5
    assert dict(cfg.bvs.mix) == {"competitive": 1, "mutual": 1, "cooperative": 1}
    assert cfg.sut.model == "level0"

    worlds, roster, bv_cmds = [], [], []
    for m in read_ros2_messages(str(out / "bag" / "bag_0.mcap")):
        if m.channel.topic == T.WORLD.name:
            worlds.append(table_columns(m.ros_msg))
        elif m.channel.topic == T.ROSTER.name:
            roster.append(table_columns(m.ros_msg))
        elif T.is_bv_command_topic(m.channel.topic):  # one table per BV node and step (bvs.nodes)
            bv_cmds.append(table_columns(m.ros_msg))
    bv_topics = {m.channel.topic for m in read_ros2_messages(str(out / "bag" / "bag_0.mcap"))
                 if T.is_bv_command_topic(m.channel.topic)}
    # 5 BVs at 1:1:1 (mix_counts) = 2 + 2 + 1: one node per policy, each answering every step
    assert bv_topics == {"/evoscen/commands/bv_competitive", "/evoscen/commands/bv_mutual",
                         "/evoscen/commands/bv_cooperative"}
    assert len(worlds) == steps + 1 and len(roster) == 1 and len(bv_cmds) == 3 * steps
    bv_cmds = [{"id": np.concatenate([c["id"] for c in bv_cmds[k:k + 3]])} for k in range(0, len(bv_cmds), 3)]
    for w in worlds:
        assert len(w["id"]) == 6
        assert sorted(w["id"].tolist()) == [0, 1, 2, 3, 4, 5]
    assert all(len(c["id"]) == 5 for c in bv_cmds)
    r = roster[0]
    assert r["role"][r["id"] == 0].tolist() == [T.ROLE_SUT]
    assert r["policy"][r["id"] == 0].tolist() == [T.POLICY_CODES["sut"]]
    # the default learned BV driver: the mix decides each BV's policy (evoscen_bringup.scenario.bv_policy_codes)
    from evoscen_sim.config.scenario_config import mix_counts

    assert cfg.bvs.driver == "learned"
    assert mix_counts(cfg) == {"competitive": 2, "mutual": 2, "cooperative": 1}  # 5 at 1:1:1
    bv_policies = Counter(int(p) for p, role in zip(r["policy"], r["role"]) if role == T.ROLE_BV)
    assert bv_policies == Counter({T.POLICY_CODES["competitive"]: 2, T.POLICY_CODES["mutual"]: 2,
                                   T.POLICY_CODES["cooperative"]: 1})


# --------------------------------------------------------------------------- determinism


def test_same_command_is_byte_identical(cli_concurrently, tmp_path):
    outs = [tmp_path / "first", tmp_path / "second"]
    for res in cli_concurrently(*[["--mode", "inprocess", "--steps", 200, "--seed", 3, "--out", out, "--quiet"]
                                  for out in outs]):
        assert res.returncode == 0, res.stderr
    assert _bag_bytes(outs[0]) == _bag_bytes(outs[1])
    assert (outs[0] / "scenario.yaml").read_bytes() == (outs[1] / "scenario.yaml").read_bytes()


def test_different_seed_differs(cli, tmp_path, recorded_run):
    out = tmp_path / "other"
    res = cli("--steps", recorded_run.steps, "--seed", recorded_run.seed + 1, "--out", out, "--quiet")
    assert res.returncode == 0, res.stderr
    assert (out / "bag" / "bag_0.mcap").read_bytes() != recorded_run.mcap_path.read_bytes()


def test_inprocess_api_is_deterministic(tmp_path):
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_sim.config.scenario_config import load_scenario_config

    cfg = load_scenario_config(None, {"steps": 100, "seed": 3})
    blobs = []
    for name in ("a", "b"):
        bag = tmp_path / name / "bag"
        summary = run_inprocess(cfg, bag_dir=bag)
        assert summary.steps == 100 and summary.bag_dir == bag
        assert summary.message_count > 0
        assert summary.bag_bytes == sum(p.stat().st_size for p in bag.iterdir())
        blobs.append(((bag / "bag_0.mcap").read_bytes(), (bag / "metadata.yaml").read_bytes()))
    assert blobs[0] == blobs[1]


# --------------------------------------------------------------------------- --no-record


def test_no_record(cli, tmp_path, summary_of):
    out = tmp_path / "out"
    res = cli("--steps", 30, "--seed", 3, "--out", out, "--no-record", "--quiet")
    assert res.returncode == 0, res.stderr
    summary = summary_of(res.stdout)
    assert summary["steps"] == 30
    assert summary["sim_time_s"] == pytest.approx(3.0)
    assert "collisions" in summary
    assert "bag" not in summary and "bag:" not in res.stdout
    assert not (out / "bag").exists()
    assert not list(out.rglob("*.mcap"))


def test_scripts_run_without_the_overlay(tmp_path: Path) -> None:
    """The README: the scripts run from the venv with or without ``ros2_ws/install/setup.sh`` sourced —
    also with the symlink install of ``make build`` (its .egg-link files name the packages)."""
    import os
    import subprocess
    import sys

    repo = Path(__file__).resolve().parents[1]
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "AMENT_PREFIX_PATH", "COLCON_PREFIX_PATH", "CMAKE_PREFIX_PATH")}
    res = subprocess.run([sys.executable, "scripts/run_scenario.py", "--mode", "inprocess", "--steps", "5",
                          "--no-record", "--quiet", "--no-plots", "--out", str(tmp_path / "o")],
                         cwd=repo, env=env, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert "steps: 5 " in res.stdout, res.stdout
