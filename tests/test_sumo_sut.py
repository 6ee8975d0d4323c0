"""SUMO's own driver as a SUT (``examples/sumo_sut``, docs/plugins.md "Example: SUMO's own driver as the SUT").

* In situations built by hand (:func:`evoscen_sim.loop.hand_built.hand_built_world`, stepped with the driver):
  a slow leader and a free lane to the left: it changes left; on the merge lane: it merges, and when
  lane 1 is a wall it stops before the lane's end, then merges once there is room; a fast follower
  closing in the target lane: it waits until the follower has passed; the traffic window's shift
  (everyone moved back 1700 m) changes nothing but ``s``.
* One SUMO simulation per process: a second driver takes libsumo, the first then stops in one line;
  a map netconvert cannot convert and a bad parameter are one line each.
* Installed (``make setup`` installs it): the node graph and the in-process
  runner write the same bag, and a small campaign runs it on Ray workers with the result of the
  same run here (e2e).

Needs libsumo and eclipse-sumo (requirements-bench.txt); skipped without them (make test-core; make setup installs them).
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("libsumo", reason="the SUMO SUT needs libsumo (pip install -r requirements-bench.txt)")

REPO = Path(__file__).resolve().parents[1]
EXAMPLE = REPO / "examples" / "sumo_sut"
sys.path.insert(0, str(REPO / "scripts"))


@pytest.fixture(scope="module")
def ss(load_example):
    return load_example("sumo_sut")


@pytest.fixture(scope="module")
def cfg():
    from evoscen_sim.config.scenario_config import load_scenario_config

    return load_scenario_config(None, {})


@pytest.fixture(scope="module")
def road():
    from evoscen_sim.road.road_model import load_road

    return load_road()


def sut_driver(ss, cfg, seed: int = 0, **params):
    return ss.make(np.array([0]), ss.SumoSutParams(**params), cfg, np.random.default_rng(seed))


def world_of(road, s, lane, speed):
    from evoscen_sim.loop.hand_built import hand_built_world

    return hand_built_world(road, s=s, lane=lane, speed=speed, roles=[1] + [0] * (len(s) - 1))


def drive(world, sut, steps: int) -> list[dict]:
    """Step ``world`` with ``sut`` driving vehicle 0, the others holding their speed: one record per step."""
    log = []
    for k in range(steps):
        throttle = np.zeros(world.n)
        request = np.zeros(world.n, dtype=np.int64)
        t, r = sut.act(world)
        assert t.shape == (1,) and r.shape == (1,) and np.isfinite(t[0]) and -1.0 <= t[0] <= 1.0 and r[0] in (-1, 0, 1)
        throttle[0], request[0] = t[0], r[0]
        rec = {"k": k, "s": float(world.s[0]), "lane": int(world.lane[0]), "v": float(world.v[0]),
               "throttle": float(t[0]), "request": int(r[0]), "others_s": world.s[1:].copy()}
        result = world.step(throttle, request)
        rec["executed"] = int(result.executed_lane_change[0])
        rec["off_road"] = 0 in result.off_road
        log.append(rec)
    return log


def requests(log: list[dict]) -> list[tuple[int, int, int]]:
    """(step, lane, request) of every executed request."""
    return [(r["k"], r["lane"], r["executed"]) for r in log if r["executed"]]


# ------------------------------------------------------------------ situations built by hand


def test_slow_leader_and_a_free_left_lane_it_changes_left(ss, cfg, road):
    # lane 2 at 25 m/s, a leader at 20 m/s 35 m ahead (bumper to bumper), lanes 1 and 3 empty
    world = world_of(road, [300, 340], [2, 2], [25, 20])
    log = drive(world, sut_driver(ss, cfg), 100)
    first = requests(log)[0]
    assert first[1:] == (2, 1) and first[0] < 30, requests(log)  # to the left, within 3 s
    assert world.lane[0] == 3 and not any(r["off_road"] for r in log)


def test_free_road_on_the_rightmost_lane_it_keeps_its_lane_and_speeds_up(ss, cfg, road):
    world = world_of(road, [300], [1], [25])
    log = drive(world, sut_driver(ss, cfg, sigma=0.0), 100)
    assert requests(log) == []
    assert log[0]["throttle"] == pytest.approx(2.6 / 3.0)  # Krauss accel 2.6 m/s² over the vehicle's 3 m/s²
    assert world.v[0] == pytest.approx(33.33, abs=0.05)  # up to the lane's limit (speed factor 1)


def test_on_the_merge_lane_it_merges(ss, cfg, road):
    world = world_of(road, [700], [0], [22])
    log = drive(world, sut_driver(ss, cfg), 100)
    assert requests(log)[0] == (0, 0, 1)  # lane 0 ends at 960 m: SUMO's strategic change, at once
    assert world.lane[0] == 1 and not any(r["off_road"] for r in log)


def test_on_the_merge_lane_beside_a_wall_it_stops_before_the_end_then_merges(ss, cfg, road):
    wall = np.arange(600.0, 1000.0, 10.0)  # lane 1 full of standing vehicles: never a gap
    world = world_of(road, [700.0, *wall], [0] + [1] * wall.size, [22.0] + [0.0] * wall.size)
    sut = sut_driver(ss, cfg)
    log = drive(world, sut, 400)
    assert requests(log) == [] and not any(r["off_road"] for r in log)
    # stopped where SUMO's lane 0 ends for cars: 927.9 m (narrower than 1.8 m beyond), centre 2.4 m behind
    assert world.lane[0] == 0 and world.v[0] < 0.01 and 915.0 < world.s[0] < 928.0 - 2.4 + 0.1
    world.s[1:] += 2000.0  # the wall gone
    world.refresh()
    log = drive(world, sut, 100)
    assert requests(log)[0][1:] == (0, 1) and world.lane[0] == 1 and not any(r["off_road"] for r in log)


def test_a_fast_follower_closing_in_the_target_lane_it_waits(ss, cfg, road):
    # as the first test, and a follower in lane 3 15 m behind closing at 36 m/s: no change until it has passed
    world = world_of(road, [300, 340, 280], [2, 2, 3], [25, 20, 36])
    log = drive(world, sut_driver(ss, cfg), 100)
    first = requests(log)[0]
    assert first[1:] == (2, 1)
    at = log[first[0]]
    assert at["others_s"][1] - at["s"] > 4.8, (first, at["s"], at["others_s"])  # the follower is ahead by then


def test_vehicles_entering_and_leaving_are_seen_at_once(ss, cfg, road):
    """A BV waiting before the road's start is not in SUMO; when it begins a new trip 20 m ahead of the
    SUT at 10 m/s (a window entry: same index, a jump) the SUT brakes in that very step; when it is
    gone again, the SUT speeds up again."""
    world = world_of(road, [300, -50], [1, 1], [25, 10])
    sut = sut_driver(ss, cfg, sigma=0.0)
    assert drive(world, sut, 1)[0]["throttle"] == pytest.approx(2.6 / 3.0)  # free road: Krauss accel
    assert "v1" not in sut.present
    world.s[1] = world.s[0] + 20.0 + 4.8  # 20 m ahead, bumper to bumper
    world.refresh()
    assert drive(world, sut, 1)[0]["throttle"] < -0.3 and "v1" in sut.present  # brakes hard
    world.s[1] = -50.0
    world.refresh()
    assert drive(world, sut, 1)[0]["throttle"] == pytest.approx(2.6 / 3.0) and "v1" not in sut.present


def test_the_shift_changes_nothing_but_s(ss, cfg, road):
    """The traffic window moves everyone back 1700 m (docs/plugins.md §10): the driver answers the
    same lane changes as without it, at the same steps, and the same throttle within 0.05 (0.15 m/s²:
    SUMO's edges differ by up to 0.2 % in length from evoscen's s, so gaps there differ a little)."""
    start = dict(s=[1950, 2010, 1990], lane=[1, 1, 2], speed=[30, 28, 33])
    runs = {}
    for shift in (True, False):  # one after the other: libsumo holds one simulation per process
        world, sut = world_of(road, **start), sut_driver(ss, cfg, sigma=0.0)
        log = drive(world, sut, 15)
        if shift:
            world.s[:] -= 1700.0
            world.refresh()
        runs[shift] = log + drive(world, sut, 30)
    assert [r["request"] for r in runs[True]] == [r["request"] for r in runs[False]]
    assert sum(r["request"] for r in runs[True]) == 1  # the change left past the slower leader, in both
    assert np.allclose([r["throttle"] for r in runs[True]], [r["throttle"] for r in runs[False]], atol=0.05)
    assert runs[True][15]["s"] == pytest.approx(runs[False][15]["s"] - 1700.0)


# ------------------------------------------------------------------ one SUMO per process; bad input


def test_a_second_sumo_sut_in_the_process_takes_libsumo_and_the_first_stops_in_one_line(ss, cfg, road):
    world = world_of(road, [300, 340], [2, 2], [25, 20])
    first, second = sut_driver(ss, cfg), sut_driver(ss, cfg)
    first.act(world)
    second.act(world)  # starts its own simulation: the first one's is closed
    with pytest.raises(ss.SumoInstanceError) as err:
        first.act(world)
    text = str(err.value)
    assert "\n" not in text and text.startswith("sumo_sut: another SUMO SUT started in this process")
    assert "one SUMO simulation per process" in text
    second.act(world)  # the second one drives on


def test_a_map_netconvert_cannot_convert_is_one_line(ss, tmp_path, monkeypatch):
    from evoscen_sim.errors import InputError

    monkeypatch.setenv("EVOSCEN_SUMO_CACHE", str(tmp_path / "cache"))
    bad = tmp_path / "bad.xodr"
    bad.write_text("<OpenDRIVE><road", encoding="utf-8")
    with pytest.raises(InputError) as err:
        ss.convert_map(bad)
    text = str(err.value)
    assert "\n" not in text and text.startswith(f"{bad}: netconvert could not convert the map for the SUMO SUT: ")
    assert list((tmp_path / "cache").iterdir()) == []  # nothing half-written left in the cache


def test_the_converted_network_is_cached_by_content(ss, tmp_path, monkeypatch, road):
    from evoscen_sim.road.road_model import DEFAULT_MAP_PATH

    monkeypatch.setenv("EVOSCEN_SUMO_CACHE", str(tmp_path / "cache"))
    net = ss.convert_map(Path(DEFAULT_MAP_PATH))
    assert net.parent == tmp_path / "cache" and net.name.startswith("onramp-")
    mtime = net.stat().st_mtime_ns
    assert ss.convert_map(Path(DEFAULT_MAP_PATH)) == net and net.stat().st_mtime_ns == mtime
    network = ss.SumoNetwork(net, road)
    # lane 0 (the merge lane) is a car lane in SUMO from 604 to 927.9 m; the mainline lanes run to the end
    assert [(round(s0), round(s1)) for s0, s1, *_ in network.spans[0]] == [(604, 900), (900, 928)]
    assert network.place(0, 950.0, clamp=False) is None and network.place(0, 950.0, clamp=True)[1] > 0
    assert network.place(4, 300.0, clamp=False) == (network.spans[4][0][2], pytest.approx(300.0))


@pytest.fixture
def registered(ss):
    from evoscen_sim.model_registry import register_model, unregister_model

    installed = any(ep.name == "sumo_sut" for ep in importlib.metadata.entry_points(group="evoscen.sut"))
    if not installed:
        register_model(ss.SPEC)
    yield ss
    if not installed:
        unregister_model(ss.SPEC.name)


def test_bad_parameters_are_one_line_naming_the_plugin(registered):
    from evoscen_sim.config.scenario_config import config_from_dict
    from evoscen_sim.errors import InputError

    with pytest.raises(InputError) as err:
        config_from_dict({"models": {"sumo_sut": {"lane_change_model": "LC2025"}}}, source="s.yaml")
    text = str(err.value)
    assert "\n" not in text and text.startswith("s.yaml: key 'models.sumo_sut.lane_change_model' = 'LC2025': "
                                                "expected one of LC2013, SL2015"), text
    with pytest.raises(InputError) as err:
        config_from_dict({"models": {"sumo_sut": {"tau": 1.0}}}, source="s.yaml")
    assert str(err.value).endswith("did you mean 'tau_s'?"), str(err.value)


def test_a_bad_parameter_on_the_command_line_is_one_line_and_nothing_runs(registered, tmp_path, capsys):
    import run_scenario

    config = tmp_path / "scenario.yaml"
    config.write_text("sut: {model: sumo_sut}\nmodels:\n  sumo_sut: {sigma: 1.5}\n", encoding="utf-8")
    code = run_scenario.main(["--mode", "inprocess", "--config", str(config), "--steps", "10", "--no-record",
                              "--quiet", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and "Traceback" not in err and len(lines) == 1, err
    assert lines[0] == f"error: {config}: key 'models.sumo_sut.sigma' = 1.5: expected a number in [0, 1] (line 3)"
    assert not (tmp_path / "out").exists()


def test_sl2015_changes_left_past_a_slow_leader_too(ss, cfg, road):
    world = world_of(road, [300, 340], [2, 2], [25, 20])
    log = drive(world, sut_driver(ss, cfg, lane_change_model="SL2015"), 100)
    first = requests(log)[0]
    assert first[1:] == (2, 1) and first[0] < 30, requests(log)
    assert world.lane[0] == 3


# ------------------------------------------------------------------ installed: both runners, a campaign


def require_installed() -> None:
    if not any(ep.name == "sumo_sut" for ep in importlib.metadata.entry_points(group="evoscen.sut")):
        pytest.skip("examples/sumo_sut is not installed (make setup installs it)")


def run_cli(*args: object) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "scripts/run_scenario.py", *map(str, args)], cwd=REPO,
                          env=dict(os.environ), capture_output=True, text=True, timeout=300, check=False)


@pytest.mark.e2e  # runs the CLI and a node graph as subprocesses
def test_installed_runs_in_both_runners_with_the_same_bag(tmp_path):
    require_installed()
    runs = {}
    for mode in ("graph", "inprocess"):
        res = run_cli("--mode", mode, "--sut", "sumo_sut", "--steps", 200, "--seed", 4, "--no-plots", "--quiet",
                      "--out", tmp_path / mode)
        assert res.returncode == 0, (mode, res.stdout, res.stderr)
        assert "pyarrow" not in res.stdout + res.stderr  # libsumo's import warning is kept quiet
        runs[mode] = (tmp_path / mode / "bag" / "bag_0.mcap").read_bytes()
    assert runs["graph"] == runs["inprocess"]


@pytest.mark.e2e  # starts a local Ray
@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_a_campaign_runs_it_on_ray_workers_with_the_result_of_the_same_run_here(tmp_path):
    require_installed()
    import pyarrow.parquet as pq
    from evoscen_experiments.campaign import run_campaign
    from evoscen_experiments.campaign_spec import expand, load_spec
    from evoscen_experiments.campaign_summary import write_results
    from evoscen_bringup.inprocess import run_inprocess

    spec_path = tmp_path / "spec.yaml"
    spec_path.write_text("name: sumo\nsteps: 100\nseeds: [0, 1]\nset: {sut.model: sumo_sut, bvs.count: 6}\n",
                         encoding="utf-8")
    spec = load_spec(spec_path)
    runs = expand(spec)
    done = run_campaign(runs, tmp_path / "out", cpus=2)
    write_results(spec, runs, tmp_path / "out")
    assert (done.runs, done.computed, done.failed) == (2, 2, [])
    table = {row["key"]: row for row in pq.read_table(tmp_path / "out" / "results.parquet").to_pylist()}
    here = run_inprocess(runs[1].cfg, bag_dir=None, evaluate=True, plots=False).report
    # a campaign's comparative column is D (docs/evaluation.md §10)
    assert table[runs[1].key]["comparative"] == here["comparative"]["score"]
    assert table[runs[1].key]["seed"] == 1
