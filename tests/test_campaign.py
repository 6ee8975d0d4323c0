"""Campaigns on Ray (evoscen_experiments.campaign, campaign_spec, campaign_summary, scripts/campaign.py; docs/campaigns.md).

* A bad spec is one line naming the file, the key and what was expected.
* Expansion: 2 SUT models x 3 seeds = 6 runs with distinct keys; the same spec and code give
  the same keys; another code version or another step count gives other keys; a ``mutant``
  axis applies the mutant's overrides (docs/mutants.md) to the cell's ``sut.model``.
* A campaign on a local Ray of 2 workers: every run once (results.parquet: 6 rows, 6 keys),
  each result equal to the same run in this process; run again: nothing computed, no result
  file rewritten.
* Ctrl-C part-way through 16 runs (the CLI in a subprocess): exit 130, finished runs kept; the same command
  again computes only the rest, the earlier result files untouched, every run once.
* A Ray worker killed (SIGKILL) while it runs a task: the task is retried, the campaign ends
  with every run exactly once (exit 0).
* A real 2-node cluster on this machine (two raylets, ray.cluster_utils.Cluster): tasks run on
  both nodes and every result equals the local run's.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from evoscen_experiments.campaign import collect_rows, run_campaign
from evoscen_experiments.campaign_spec import expand, load_spec
from evoscen_experiments.campaign_summary import write_results
from evoscen_sim.errors import InputError

pytestmark = [pytest.mark.e2e, pytest.mark.filterwarnings("ignore::DeprecationWarning")]

REPO = Path(__file__).resolve().parents[1]
SMALL = """
name: small
steps: 40
seeds: [0, 1, 2]
set: {bvs.count: 4, spawn.ramp_vehicles: 1}
grid:
  sut.model: [mobil, level0]
compare: {axis: sut.model, reference: mobil}
"""


def write_spec(tmp_path: Path, text: str, name: str = "spec.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("text, needle", [
    ("grids: {}\n", "key 'grids' = {}: expected one of the keys name, config"),
    ("seeds: []\n", "key 'seeds' = []: expected a list of distinct integers >= 0, or {first: N, count: M}"),
    ("grid: {sut.model: []}\n", "key 'grid.sut.model' = []: expected a non-empty list of distinct values"),
    ("grid: {mutant: [intact, nosuch]}\n", "key 'grid.mutant' = 'nosuch': expected 'intact' or a mutant of"),
    ("steps: 0\n", "key 'steps' = 0: expected an integer >= 1"),
    ("grid: {sut.model: [mobil]}\ncompare: {axis: bvs.driver, reference: x}\n", "key 'compare' ="),
    ("record: some\n", "key 'record' = 'some': expected 'none' (scores only), 'events' (critical-event clips) or 'all'"),
    ("clip_s: 0\n", "key 'clip_s' = 0: expected seconds in (0, 60] on either side of an event"),
])
def test_bad_spec_is_one_line_naming_file_and_key(tmp_path, text, needle):
    path = write_spec(tmp_path, text)
    with pytest.raises(InputError) as exc:
        load_spec(path)
    msg = str(exc.value)
    assert msg.startswith(str(path)) and needle in msg and "\n" not in msg, msg


def test_a_bad_scenario_value_names_the_spec_and_the_cell(tmp_path):
    spec = load_spec(write_spec(tmp_path, "grid: {sut.model: [mobil, nosuch]}\n"))
    with pytest.raises(InputError) as exc:
        expand(spec, version="v")
    assert str(exc.value).startswith(f"{spec.path}: cell {{'sut.model': 'nosuch'}}: ") and "\n" not in str(exc.value)


@pytest.mark.parametrize("name, cells, seeds", [("intelligence", 4, 10), ("complexity", 3, 20),
                                               ("mobil-mutants", 11, 10), ("mutants", None, None)])
def test_shipped_specs_load_and_expand(name, cells, seeds):
    spec = load_spec(REPO / "examples" / "campaigns" / f"{name}.yaml")
    runs = expand(spec, version="v1")
    if cells is not None:
        assert len(runs) == cells * seeds and len(spec.seeds) == seeds
    assert len({r.key for r in runs}) == len(runs)


def test_summary_gives_complexity_per_cell_by_hand(tmp_path):
    from evoscen_experiments.campaign_summary import summary_markdown

    spec = load_spec(write_spec(tmp_path, SMALL))
    runs = expand(spec, version="v1")
    rows = []
    for i, r in enumerate(runs):  # mobil: C 0.1, 0.2, 0.3; level0: undefined (a run shorter than a window)
        rows.append({"key": r.key, "seed": r.seed, "sut.model": dict(r.cell)["sut.model"], "comparative": 0.5,
                     "comparative_safety": 0.5, "comparative_progress": 0.5, "comparative_lane_change_time": 0.5,
                     "comparative_interaction": 0.5, "intelligence": 0.5,
                     "complexity": [0.1, 0.2, 0.3][i] if i < 3 else None, "collisions": 0, "exposures": 0})
    text = summary_markdown(spec, runs, rows)
    # D first with its terms, the method's I, then K; no heading names D "intelligence"
    assert ("| sut.model | n (count) | D (ratio) | S (ratio) | P (ratio) | L (ratio) | X (ratio) | "
            "I, the method's (ratio) | K, the scenario's (ratio) | SUT collisions (count) |") in text
    # mean 0.2, sd 0.1, t(0.975, 2) = 4.3027: half-width 4.3027 * 0.1 / sqrt(3) = 0.2484
    same = "0.5000 ± 0.0000 | " * 6
    assert f"| mobil | 3 | {same}0.2000 ± 0.2484 |" in text
    assert f"| level0 | 3 | {same}– |" in text


def test_traffic_columns_of_a_report():
    from evoscen_experiments.campaign import traffic_columns

    cols = traffic_columns({"traffic": {"mean_bvs": 2.0, "min_window_mean_bvs": 1.0, "empty_share": 0.25}})
    assert cols == {"traffic_mean_bvs": 2.0, "traffic_min_window_mean_bvs": 1.0, "traffic_empty_share": 0.25}
    # a run under half a traffic window has no window mean: NaN, as an undefined score
    short = traffic_columns({"traffic": {"mean_bvs": 3.0, "min_window_mean_bvs": None, "empty_share": 0.0}})
    assert short["traffic_mean_bvs"] == 3.0 and math.isnan(short["traffic_min_window_mean_bvs"])


def test_expansion_and_keys(tmp_path):
    spec = load_spec(write_spec(tmp_path, SMALL))
    runs = expand(spec, version="v1")
    assert [(dict(r.cell)["sut.model"], r.seed) for r in runs] == [
        ("mobil", 0), ("mobil", 1), ("mobil", 2), ("level0", 0), ("level0", 1), ("level0", 2)]
    assert all(r.cfg.steps == 40 and r.cfg.bvs.count == 4 and r.cfg.seed == r.seed for r in runs)
    assert all(r.cfg.recording.enabled is False for r in runs)  # record: none
    keys = [r.key for r in runs]
    assert len(set(keys)) == 6 and keys == [r.key for r in expand(spec, version="v1")]
    assert not set(keys) & {r.key for r in expand(spec, version="v2")}
    longer = load_spec(write_spec(tmp_path, SMALL.replace("steps: 40", "steps: 41"), "longer.yaml"))
    assert not set(keys) & {r.key for r in expand(longer, version="v1")}
    mut = load_spec(write_spec(tmp_path, "set: {sut.model: mobil}\ngrid: {mutant: [intact, stale]}\n", "m.yaml"))
    intact, stale = expand(mut, version="v1")
    from evoscen_sut.mutants import mutant_overrides

    assert intact.cfg.sut.model == "mobil" and intact.key != stale.key
    reference = __import__("evoscen_sim.config.scenario_config", fromlist=["x"]).load_scenario_config(
        None, {"sut.model": "mobil", "recording.enabled": "false", "seed": "0", **mutant_overrides("mobil", "stale")})
    assert stale.cfg == reference


@pytest.fixture(scope="module")
def local_campaign(tmp_path_factory):
    """The SMALL campaign on a local Ray of 2 workers, run twice."""
    tmp = tmp_path_factory.mktemp("campaign")
    spec = load_spec(write_spec(tmp, SMALL))
    runs = expand(spec)
    first = run_campaign(runs, tmp / "out", cpus=2)
    write_results(spec, runs, tmp / "out")
    mtimes = {r.key: (tmp / "out" / "runs" / r.key / "result.json").stat().st_mtime_ns for r in runs}
    second = run_campaign(runs, tmp / "out", cpus=2)
    return {"spec": spec, "runs": runs, "out": tmp / "out", "first": first, "second": second, "mtimes": mtimes}


def test_every_run_once_and_equal_to_the_same_run_here(local_campaign):
    import pyarrow.parquet as pq

    from evoscen_bringup.inprocess import run_inprocess

    runs, out, first = local_campaign["runs"], local_campaign["out"], local_campaign["first"]
    assert (first.runs, first.already_done, first.computed, first.failed) == (6, 0, 6, [])
    table = pq.read_table(out / "results.parquet").to_pylist()
    assert sorted(row["key"] for row in table) == sorted(r.key for r in runs)
    here_run = run_inprocess(runs[4].cfg, bag_dir=None, evaluate=True, plots=False)
    here, here_plot = here_run.report, here_run.plot
    row = next(row for row in table if row["key"] == runs[4].key)
    from evoscen_eval.scoring.metrics import compared_scores

    assert row["comparative"] == compared_scores(here)["intelligence"] == here["comparative"]["score"]
    assert row["intelligence"] == here["intelligence"]["score"]  # always the method's I
    assert row["comparative_progress"] == here["comparative"]["progress"]["score"] and row["score_form"] == "comparative"
    assert row["collisions"] == here["safety"]["collisions"] and row["seed"] == 1 and row["sut.model"] == "level0"
    assert row["traffic_mean_bvs"] == here["traffic"]["mean_bvs"]
    assert row["traffic_empty_share"] == here["traffic"]["empty_share"]
    report = json.loads((out / "runs" / runs[4].key / "report.json").read_text())
    assert report["intelligence"]["score"] == here["intelligence"]["score"]
    summary = (out / "summary.md").read_text()
    assert "## Paired by seed: each other sut.model − mobil (D, the comparative score)" in summary
    assert "| level0 | 3 |" in summary  # the paired row: 3 shared seeds
    for name in ("summary.png", "distributions.png"):
        assert (out / name).stat().st_size > 0 and f"]({name})" in summary
    plot = json.loads((out / "runs" / runs[4].key / "plot.json").read_text())
    assert plot["speed_hist"] == here_plot.speed_hist.tolist() and plot["ttc_hist"] == here_plot.ttc_hist.tolist()


def test_running_again_computes_nothing(local_campaign):
    second, runs, out = local_campaign["second"], local_campaign["runs"], local_campaign["out"]
    assert (second.already_done, second.computed) == (6, 0)
    for r in runs:
        assert (out / "runs" / r.key / "result.json").stat().st_mtime_ns == local_campaign["mtimes"][r.key]
    assert len(collect_rows(runs, out)) == 6


def _cli(spec: Path, out: Path, *extra: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "scripts/campaign.py", str(spec), "--out", str(out), "--cpus", "2",
                             *extra], cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)


def _finish(proc: subprocess.Popen, timeout: float) -> tuple[str, str]:
    """The CLI's output once it has ended (its whole process group killed if it has not in time)."""
    try:
        return proc.communicate(timeout=timeout)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()


def _results(out: Path) -> list[Path]:
    return sorted((out / "runs").glob("*/result.json")) if (out / "runs").is_dir() else []


def _wait_for(pred, timeout: float = 120.0) -> None:
    end = time.monotonic() + timeout
    while not pred():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.2)


# 16 runs of 3,000 steps with the default 20 BVs (~1 s each once a worker is warm, a few times that
# under load; ~8 s for two workers): Ctrl-C and the kill land while runs remain, however fast the machine
LONG = """
name: long
steps: 3000
seeds: {first: 0, count: 8}
grid:
  sut.model: [mobil, level0]
"""


def test_ctrl_c_then_the_same_command_computes_only_the_rest(tmp_path):
    import pyarrow.parquet as pq

    spec, out = write_spec(tmp_path, LONG), tmp_path / "out"
    proc = _cli(spec, out)
    try:
        _wait_for(lambda: len(_results(out)) >= 2)
        os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C reaches the whole foreground group, Ray's workers too
    finally:
        _out, err = _finish(proc, 60)
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    kept = {p: p.stat().st_mtime_ns for p in _results(out)}
    assert 2 <= len(kept) < 16
    again = _cli(spec, out)
    stdout, err = again.communicate(timeout=300)
    assert again.returncode == 0, err
    assert f"{16 - len(kept)} runs computed" in stdout and f"{len(kept)} already done" in stdout
    assert all(p.stat().st_mtime_ns == t for p, t in kept.items())
    keys = [row["key"] for row in pq.read_table(out / "results.parquet").to_pylist()]
    assert len(keys) == 16 == len(set(keys))


def _task_workers(root: int) -> list[int]:
    """Pids of Ray workers (descendants of ``root``) running a campaign task (title ``ray::execute``)."""
    out = subprocess.run(["ps", "-e", "-o", "pid=,ppid=,args="], capture_output=True, text=True, check=True).stdout
    children: dict[int, list[int]] = {}
    title: dict[int, str] = {}
    for line in out.splitlines():
        pid, ppid, args = line.strip().split(None, 2)
        children.setdefault(int(ppid), []).append(int(pid))
        title[int(pid)] = args
    found, stack = [], [root]
    while stack:
        pid = stack.pop()
        for child in children.get(pid, []):
            if title[child].startswith("ray::execute"):
                found.append(child)
            stack.append(child)
    return found


def test_a_killed_worker_is_retried_and_every_run_counts_once(tmp_path):
    import pyarrow.parquet as pq

    spec, out = write_spec(tmp_path, LONG), tmp_path / "out"
    proc = _cli(spec, out)
    try:
        _wait_for(lambda: len(_results(out)) >= 1 and _task_workers(proc.pid))
        before = set(_task_workers(proc.pid))  # the workers of the 2 CPUs: busy, or done already
        before |= {json.loads(p.read_text())["pid"] for p in _results(out)}
        os.kill(min(_task_workers(proc.pid)), signal.SIGKILL)
    finally:
        _out, err = _finish(proc, 300)
    assert proc.returncode == 0, err
    keys = [row["key"] for row in pq.read_table(out / "results.parquet").to_pylist()]
    assert len(keys) == 16 == len(set(keys))
    pids = {row["pid"] for row in pq.read_table(out / "results.parquet").to_pylist()}
    assert pids - before, (pids, before)  # a new worker took over the killed one's task


def test_a_two_node_cluster_runs_tasks_on_both_nodes_with_the_local_results(local_campaign, tmp_path):
    import ray
    from ray.cluster_utils import Cluster

    from evoscen_experiments.campaign import OBJECT_STORE_BYTES

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False,
                                                           "object_store_memory": OBJECT_STORE_BYTES})
    try:
        cluster.add_node(num_cpus=1, object_store_memory=OBJECT_STORE_BYTES)
        cluster.wait_for_nodes()
        runs = local_campaign["runs"]
        result = run_campaign(runs, tmp_path / "out", address=cluster.address)
    finally:
        if ray.is_initialized():
            ray.shutdown()
        cluster.shutdown()
    assert result.computed == 6 and not result.failed
    assert len(result.nodes) == 2, result.nodes
    here = {row["key"]: row for row in collect_rows(runs, local_campaign["out"])}
    for row in collect_rows(runs, tmp_path / "out"):
        for name in ("comparative", "intelligence", "intelligence_safety", "intelligence_efficiency", "collisions",
                     "exposures"):
            assert row[name] == here[row["key"]][name] or (row[name] != row[name] and here[row["key"]][name] != here[row["key"]][name]), name


CLIPS = """
name: clips
steps: 300
seeds: [19]
set: {sut.model: mobil, bvs.count: 20, spawn.ramp_vehicles: 1, evaluation.ttc_threshold_s: 6.0, bvs.makeup: uniform}
record: events
clip_s: 2.0
"""


def test_critical_events_become_clips_pictures_and_reproducible_commands(tmp_path):
    """With a 6 s TTC threshold this run (seed 19, 20 BVs of the uniform make-up in the traffic window;
    seeds 0-29 scanned: the only one with two events in 300 steps) has 2 exposures. Every SUT collision and exposure of the
    run becomes a clip of +-2 s (20 states each side at dt 0.1 s, clamped to the run) with the
    latched map, a picture and a command; the command's run holds the very same world states;
    ``record: events`` keeps no whole bag; the gallery lists collisions first, then exposures
    by falling severity."""
    import shlex

    from evoscen_record.bag_reader import open_bag_reader

    spec = load_spec(write_spec(tmp_path, CLIPS))
    runs = expand(spec)
    out = tmp_path / "out"
    result = run_campaign(runs, out, record=spec.record, clip_s=spec.clip_s, cpus=1)
    write_results(spec, runs, out)
    assert result.computed == 1 and not result.failed
    run_dir = out / "runs" / runs[0].key
    report = json.loads((run_dir / "report.json").read_text())
    clips = json.loads((run_dir / "clips.json").read_text())
    n_events = report["safety"]["collisions"] + report["safety"]["exposures"]
    assert n_events >= 2 and len(clips) == n_events
    assert not (run_dir / "bag").exists()  # record: events keeps the clips only
    first = clips[0]
    k = first["state"]
    assert (first["from_state"], first["to_state"]) == (max(0, k - 20), min(300, k + 20))
    clip_msgs = list(open_bag_reader(run_dir / first["clip"]))
    world = [(t, d) for topic, _ty, t, d in clip_msgs if topic == "/evoscen/world"]
    assert [t for t, _ in world] == [s * 100_000_000 for s in range(first["from_state"], first["to_state"] + 1)]
    assert sum(topic == "/evoscen/map_markers" for topic, *_ in clip_msgs) == 1
    assert all((run_dir / c["png"]).stat().st_size > 0 for c in clips)
    # the reproduce command: the same world states, byte for byte
    argv = shlex.split(first["command"])
    out_arg = argv.index("--out") + 1
    argv[out_arg] = str(tmp_path / "repro")
    res = subprocess.run([sys.executable, *argv[1:], "--quiet", "--no-plots"], cwd=REPO, capture_output=True,
                         text=True, timeout=300, check=False)
    assert res.returncode == 0, res.stderr
    repro = {t: d for topic, _ty, t, d in open_bag_reader(tmp_path / "repro" / "bag") if topic == "/evoscen/world"}
    assert all(repro[t] == d for t, d in world)
    gallery = (out / "gallery.md").read_text().splitlines()
    rows = [line.split(" | ") for line in gallery if line.startswith("| ") and line[2].isdigit()]
    assert len(rows) == n_events
    kinds = [r[1] for r in rows]
    assert kinds == sorted(kinds)  # every collision before every exposure
    sev = [float(r[5]) for r in rows if r[1] == "exposure"]
    assert sev == sorted(sev, reverse=True)


def test_a_full_disk_mid_campaign_stops_it_and_the_same_command_resumes(tmp_path):
    """The output's disk fills mid-campaign (a real tmpfs sized for about half the runs' files):
    one line, status 5, no run marked done that was not written whole; after space is freed the
    same command computes exactly the rest, and the results equal an undisturbed campaign's."""
    import pyarrow.parquet as pq

    if os.geteuid() != 0:
        pytest.skip("needs root to mount a tmpfs")
    spec = write_spec(tmp_path, SMALL)
    ref = tmp_path / "ref"
    proc = _cli(spec, ref)
    _out, err = _finish(proc, 300)
    assert proc.returncode == 0, err
    page = 4096
    per_run = [sum(-(-f.stat().st_size // page) * page for f in d.iterdir()) for d in sorted((ref / "runs").iterdir())]
    mnt = tmp_path / "fs"
    mnt.mkdir()
    size_kib = (sum(per_run[:3]) + page) // 1024
    if subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size_kib}k", "tmpfs", str(mnt)]).returncode:
        pytest.skip("cannot mount a tmpfs")
    try:
        out = mnt / "out"
        proc = _cli(spec, out)
        _out, err = _finish(proc, 300)
        assert proc.returncode == 5, err
        assert "Traceback" not in err
        errors = [ln for ln in err.splitlines() if ln.startswith("error:")]
        assert len(errors) == 1 and "No space left on device (ENOSPC)" in errors[0], err
        assert "run the same command again to continue" in errors[0]
        done = _results(out)
        assert 1 <= len(done) < 6
        for p in done:  # every run marked done is whole
            json.loads(p.read_text())
            assert (p.parent / "report.json").is_file() and (p.parent / "plot.json").is_file()
        assert not list(out.rglob("*.tmp"))
        kept = {p: p.stat().st_mtime_ns for p in done}
        assert subprocess.run(["mount", "-o", "remount,size=64m", str(mnt)]).returncode == 0  # space freed
        again = _cli(spec, out)
        stdout, err = _finish(again, 300)
        assert again.returncode == 0, err
        assert f"{6 - len(kept)} runs computed" in stdout and f"{len(kept)} already done" in stdout
        assert all(p.stat().st_mtime_ns == t for p, t in kept.items())
        volatile = {"wall_time_s", "node", "pid"}

        def rows(d: Path) -> list[dict]:
            table = pq.read_table(d / "results.parquet").to_pylist()
            return sorted(({k: v for k, v in row.items() if k not in volatile} for row in table), key=lambda r: r["key"])

        got, want = rows(out), rows(ref)
        assert len(got) == 6 == len({r["key"] for r in got})
        assert json.dumps(got, sort_keys=True) == json.dumps(want, sort_keys=True)
        for d in sorted((ref / "runs").iterdir()):
            assert (out / "runs" / d.name / "report.json").read_bytes() == (d / "report.json").read_bytes()
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


def test_a_killed_driver_leaves_no_ray_processes_once_the_next_campaign_starts(tmp_path):
    """SIGKILL to the driver alone (its Ray's agents outlive it, reparented to init): the same
    command names and ends them, then completes the campaign with every run exactly once."""
    import pyarrow.parquet as pq

    from evoscen_experiments.ray_leftovers import DRIVER_FILE, session_processes

    spec, out = write_spec(tmp_path, LONG), tmp_path / "out"
    proc = _cli(spec, out)
    try:
        _wait_for(lambda: len(_results(out)) >= 1 and (out / DRIVER_FILE).exists())
        session = json.loads((out / DRIVER_FILE).read_text())["session_dir"]
        os.kill(proc.pid, signal.SIGKILL)  # the driver only, not its process group
        proc.wait(timeout=30)
    finally:
        _finish(proc, 30)
    time.sleep(2)
    left = [pid for pid, _ in session_processes(session)]
    assert left  # Ray's agents outlive a driver killed with SIGKILL (measured: ray::DashboardAgent, ray::RuntimeEnvAgent)
    again = _cli(spec, out)
    stdout, err = _finish(again, 400)
    assert again.returncode == 0, err
    lines = [ln for ln in err.splitlines() if ln.startswith("campaign: ended")]
    # (some of Ray's processes may still be ending by themselves when it starts: the agents are not)
    assert len(lines) == 1 and any(f"(pid {pid})" in lines[0] for pid in left), err
    assert session_processes(session) == [] or all(
        Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z"
        for pid, _ in session_processes(session))
    assert not (out / DRIVER_FILE).exists()
    keys = [row["key"] for row in pq.read_table(out / "results.parquet").to_pylist()]
    assert len(keys) == 16 == len(set(keys))


def test_a_fault_of_the_host_in_a_worker_is_found_behind_rays_error():
    """A run's HostFault raised in a Ray worker reaches the driver wrapped by Ray; the driver finds
    it (and stops the campaign with one line instead of failing every run alike)."""
    import ray

    from evoscen_experiments.campaign import _host_fault_of
    from evoscen_sim.errors import HostFault

    def full() -> None:
        raise HostFault.of(OSError(28, "No space left on device"), "/tmp/evoscen-run-x/bag/bag_0.mcap")

    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False, configure_logging=False)
    try:
        with pytest.raises(Exception) as info:  # Ray's wrapper, whatever its class
            ray.get(ray.remote(num_cpus=1, max_retries=0)(full).remote())
    finally:
        ray.shutdown()
    fault = _host_fault_of(info.value)
    assert fault is not None and fault.cause == "No space left on device (ENOSPC)"
    assert str(fault.path) == "/tmp/evoscen-run-x/bag/bag_0.mcap"
    assert _host_fault_of(RuntimeError("not the disk")) is None
