"""The FISS / FISS+ plug-in (``examples/fiss_sut``, fiss-planner 1.0.0) and the check of every driver's answer.

* In situations built by hand (:func:`evoscen_sim.loop.hand_built.hand_built_world`): a slow leader and a free
  lane to the left, it changes left; on the merge lane it leaves it, and where it cannot it waits and
  brakes; a follower closing fast in the target lane makes it wait; no request during a change nor
  before it has settled.
* A bad ``models.fiss`` value is one line naming the key.
* Installed (``pip install -e examples/fiss_sut``, as ``make setup`` does): ``--sut fiss`` writes the
  same bag in the node graph and in-process (e2e), and runs in a campaign on Ray (e2e).
* A driver whose answer is not finite, of the wrong shape or with a lane change outside {-1, 0, 1}
  stops the run with one line naming the model (exit 2), in-process and in the node graph.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("fiss_planner", reason="fiss-planner is not installed: pip install -e examples/fiss_sut")

REPO = Path(__file__).resolve().parents[1]
EXAMPLE = REPO / "examples" / "fiss_sut"
sys.path.insert(0, str(REPO / "scripts"))


@pytest.fixture(scope="module")
def fs(load_example):
    """``fiss_sut.py`` as the module ``fiss_sut`` (as the installed package imports it)."""
    return load_example("fiss_sut")


@pytest.fixture(scope="module")
def cfg():
    from evoscen_sim.config.scenario_config import load_scenario_config

    return load_scenario_config(None, {})


@pytest.fixture(scope="module")
def road():
    from evoscen_sim.road.road_model import load_road

    return load_road()


def driver(fs, cfg, **params):
    return fs.make(np.array([0]), fs.FissSutParams(**params), cfg, np.random.default_rng(0))


def world_of(road, s, lane, speed):
    from evoscen_sim.loop.hand_built import hand_built_world

    return hand_built_world(road, s=s, lane=lane, speed=speed, roles=[1] + [0] * (len(s) - 1))


def decide(fs, cfg, road, s, lane, speed, **params) -> tuple[float, int]:
    """(throttle, request) of the SUT (vehicle 0) in a hand-built world; the others are BVs."""
    throttle, request = driver(fs, cfg, **params).act(world_of(road, s, lane, speed))
    assert throttle.shape == (1,) and request.shape == (1,) and -1.0 <= throttle[0] <= 1.0
    return float(throttle[0]), int(request[0])


# lane 1 at 300 m: the merge lane (lane 0) exists only on [600, 960) m, so the only lane beside is lane 2


def test_slow_leader_and_a_free_left_lane_it_changes_left(fs, cfg, road):
    # a leader 30 m ahead (25.2 m bumper gap) at 20 m/s, the SUT at 28 m/s: closing at 8 m/s, lane 2 empty
    throttle, request = decide(fs, cfg, road, [300, 330], [1, 1], [28, 20])
    assert request == 1
    # alone, below the 30 m/s desired speed: keeps its lane and speeds up
    throttle, request = decide(fs, cfg, road, [300], [1], [28])
    assert request == 0 and throttle > 0
    # the same leader 150 m ahead is no reason to change (closing at 8 m/s it is more than the 5 s horizon away)
    assert decide(fs, cfg, road, [300, 450], [1, 1], [28, 20])[1] == 0
    # lane 4 is the leftmost: with the slow leader there it goes right (lane 3 is free), never further left
    assert decide(fs, cfg, road, [300, 330], [4, 4], [28, 20])[1] == -1


def test_a_follower_closing_fast_in_the_target_lane_makes_it_wait(fs, cfg, road):
    # a follower in lane 2, 20 m behind (15.2 m bumper gap), at the SUT's speed: the change is safe
    assert decide(fs, cfg, road, [300, 330, 280], [1, 1, 2], [28, 20, 28])[1] == 1
    # the same follower at 36 m/s (closing at 8 m/s, 1.9 s to contact): it waits
    throttle, request = decide(fs, cfg, road, [300, 330, 280], [1, 1, 2], [28, 20, 36])
    assert request == 0 and throttle < 0  # and slows down behind its leader


def test_the_merge_lane_is_left_and_where_it_cannot_be_it_waits_braking(fs, cfg, road):
    assert decide(fs, cfg, road, [700], [0], [22])[1] == 1  # lane 0 ends at 960 m: left, though nobody is ahead
    # a vehicle beside it in lane 1 at 900 m: no change, and no trajectory stays in the lane past its end
    # 60 m ahead: the planner finds none valid, the adapter keeps the lane and brakes: IDM with the lane's
    # end as a standing obstacle (60 m - half its length - lane_end_margin_m ahead): full braking
    sut = driver(fs, cfg)
    throttle, request = sut.act(world_of(road, [900, 900], [0, 1], [22, 22]))
    assert request[0] == 0 and not sut.last[0].success
    p = fs.FissSutParams()
    gap = road.lane_end_s[0] - 900 - 2.4 - p.lane_end_margin_m
    wanted = p.min_gap_m + 22 * p.time_headway_s + 22 * 22 / (2 * np.sqrt(p.fallback_accel_mps2 * p.fallback_comfort_decel_mps2))
    expected = p.fallback_accel_mps2 * (1 - (22 / 30) ** 4 - (wanted / gap) ** 2)
    assert throttle[0] == pytest.approx(max(expected / cfg.vehicle.max_brake_mps2, -1.0)) and throttle[0] < -0.3


def drive(world, sut, steps: int) -> list:
    """Step ``world`` with ``sut`` driving vehicle 0, the others holding their speed; the (request, StepResult)s."""
    out = []
    for _ in range(steps):
        throttle = np.zeros(world.n)
        request = np.zeros(world.n, dtype=np.int64)
        throttle[0], request[0] = (a[0] for a in sut.act(world))
        out.append((int(request[0]), world.step(throttle, request)))
    return out


def test_merges_from_the_merge_lane_before_its_end(fs, cfg, road):
    world = world_of(road, [700.0], [0], [22.0])
    sut, done_at = driver(fs, cfg), []
    for _ in range(150):
        _, result = drive(world, sut, 1)[0]
        assert 0 not in result.off_road
        done_at += [(f, t, float(world.s[0])) for i, f, t, _ in result.lane_changes_completed if i == 0]
    assert [(f, t) for f, t, _ in done_at] == [(0, 1)] and done_at[0][2] < road.lane_end_s[0] and world.lane[0] == 1


def test_requests_only_with_no_change_under_way_and_once_settled(fs, cfg, road):
    """Slow leaders in lanes 1 and 2: 1 -> 2, then 2 -> 3; a request only with no change under way and the
    SUT within settle_tolerance_m of its lane's centre line."""
    world = world_of(road, [300, 340, 360], [1, 1, 2], [25, 20, 20])
    sut = driver(fs, cfg)
    tol = fs.FissSutParams().settle_tolerance_m
    completed = []
    for _ in range(150):
        changing, lane = int(world.lane_change[0]), int(world.lane[0])
        off_centre = abs(world.d[0] - road.lane_center_d(lane, world.s[0]))
        request, result = drive(world, sut, 1)[0]
        if request:
            assert changing == 0 and off_centre <= tol, (changing, off_centre)
        completed += [(f, t) for i, f, t, _ in result.lane_changes_completed if i == 0]
    assert completed[:2] == [(1, 2), (2, 3)], completed


def test_bad_parameters_are_one_line(fs, tmp_path, capsys):
    from evoscen_sim.config.scenario_config import config_from_dict
    from evoscen_sim.errors import InputError
    from evoscen_sim.model_registry import model_names, register_model, unregister_model

    installed = "fiss" in model_names("sut")
    if not installed:
        register_model(fs.SPEC)
    try:
        for models, expected in [
            ({"planner": "fiss_pluss"}, "key 'models.fiss.planner' = 'fiss_pluss': expected one of fop, fop_plus, "
                                        "fiss, fiss_plus; did you mean 'fiss_plus'?"),
            ({"horizon_s": [5, 3]}, "key 'models.fiss.horizon_s' = [5, 3]: expected a list [lo, hi] of two numbers "
                                    "with lo <= hi, both in [0.5, 10]"),
            ({"num_width": 0}, "key 'models.fiss.num_width' = 0: expected an integer in [1, 20]"),
            ({"settle_tolerance": 1}, "key 'models.fiss.settle_tolerance': unknown key"),
        ]:
            with pytest.raises(InputError) as err:
                config_from_dict({"models": {"fiss": models}}, source="s.yaml")
            text = str(err.value)
            assert "\n" not in text and text.startswith(f"s.yaml: {expected}"), text
    finally:
        if not installed:
            unregister_model("fiss")


# ------------------------------------------------------------------ installed into the .venv


def installed() -> bool:
    from evoscen_sim.model_registry import model_names

    return "fiss" in model_names("sut")


needs_install = pytest.mark.skipif("not installed()", reason="pip install -e examples/fiss_sut (make setup does)")


def run_cli(*args: object, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "scripts/run_scenario.py", *map(str, args)], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=300, check=False)


@pytest.mark.e2e
@needs_install
def test_installed_fiss_writes_the_same_bag_in_both_runners(tmp_path):
    bags = {}
    for mode in ("graph", "inprocess"):
        res = run_cli("--mode", mode, "--sut", "fiss", "--steps", 200, "--seed", 3, "--no-plots", "--quiet",
                      "--out", tmp_path / mode)
        assert res.returncode == 0, (mode, res.stdout, res.stderr)
        bags[mode] = (tmp_path / mode / "bag" / "bag_0.mcap").read_bytes()
    assert bags["graph"] == bags["inprocess"]
    assert "model: fiss" in (tmp_path / "graph" / "scenario.yaml").read_text(encoding="utf-8")


@pytest.mark.e2e
@needs_install
@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_installed_fiss_runs_in_a_campaign_on_ray(tmp_path):
    import pyarrow.parquet as pq
    from evoscen_experiments.campaign_spec import expand, load_spec
    from evoscen_bringup.inprocess import run_inprocess

    spec = tmp_path / "fiss.yaml"
    spec.write_text("name: fiss\nsteps: 100\nseeds: [0, 1]\nset: {bvs.count: 6, sut.model: fiss}\n", encoding="utf-8")
    res = subprocess.run([sys.executable, "scripts/campaign.py", str(spec), "--out", str(tmp_path / "out"),
                          "--cpus", "2"], cwd=REPO, capture_output=True, text=True, timeout=300, check=False)
    assert res.returncode == 0, (res.stdout, res.stderr)
    rows = pq.read_table(tmp_path / "out" / "results.parquet").to_pylist()
    assert sorted(row["seed"] for row in rows) == [0, 1]
    run = next(r for r in expand(load_spec(spec)) if r.seed == 1)
    assert run.cfg.sut.model == "fiss"
    here = run_inprocess(run.cfg, bag_dir=None, evaluate=True, plots=False).report
    row = next(row for row in rows if row["key"] == run.key)
    # the Ray worker ran the same planner; a campaign's comparative column is D (docs/evaluation.md §10)
    assert row["comparative"] == here["comparative"]["score"]


# ------------------------------------------------------------------ a driver's answer is checked


class BadDriver:
    """Answers well for 3 steps, then as ``kind`` says."""

    def __init__(self, vehicles, kind: str) -> None:
        self.n, self.kind = len(vehicles), kind

    def act(self, view):
        throttle, lane_change = np.zeros(self.n), np.zeros(self.n, dtype=np.int64)
        if view.step_index < 3:
            return throttle, lane_change
        if self.kind == "nan":
            throttle[:] = np.nan
        elif self.kind == "inf":
            throttle[:] = -np.inf
        elif self.kind == "shape":
            return np.zeros(self.n + 1), lane_change
        elif self.kind == "lane":
            lane_change[:] = 2
        elif self.kind == "single":
            return throttle
        return throttle, lane_change


BAD = {
    "nan": "act() returned throttle nan (entry 0); expected a finite number in [-1, 1]",
    "inf": "act() returned throttle -inf (entry 0); expected a finite number in [-1, 1]",
    "shape": "act() returned a throttle of shape (2,); expected shape (1,), one per vehicle",
    "lane": "act() returned lane_change 2 (entry 0); expected -1, 0 or 1",
    "single": "act() returned a ndarray; expected a pair (throttle, lane_change) of arrays, one entry per vehicle",
}


def one_error_line(stderr: str) -> str:
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in stderr, stderr
    return lines[0]


@pytest.mark.parametrize("kind", sorted(BAD))
def test_a_bad_answer_in_process_is_one_line_naming_the_model(kind, tmp_path, capsys):
    import run_scenario
    from evoscen_sim.model_registry import ModelSpec, register_model, unregister_model

    register_model(ModelSpec(name="bad_sut", roles=("sut",), factory=lambda v, p, c, r: BadDriver(v, kind)))
    try:
        code = run_scenario.main(["--mode", "inprocess", "--sut", "bad_sut", "--steps", "20", "--no-record",
                                  "--quiet", "--out", str(tmp_path / "out")])
    finally:
        unregister_model("bad_sut")
    line = one_error_line(capsys.readouterr().err)
    assert code == 2 and line == f"error: sut model 'bad_sut': {BAD[kind]}", line


def test_checked_answer_passes_a_good_answer_through_and_names_a_bv_model():
    from evoscen_sim.errors import InputError
    from evoscen_sim.model_registry import checked_answer

    throttle, lane_change = np.array([0.5, -1.0]), np.array([1, -1])
    assert checked_answer(object(), (throttle, lane_change), 2) == (throttle, lane_change)
    with pytest.raises(InputError, match=r"^driver model 'BadDriver': act\(\) returned lane_change 0.5 \(entry 1\)"):
        checked_answer(BadDriver([0, 1], "nan"), (throttle, np.array([0, 0.5])), 2)


@pytest.mark.parametrize("dtypes", [(np.float64, np.int64), (np.float32, np.int32), (np.float64, np.int8)])
def test_the_quick_check_takes_exactly_the_good_answers_whatever_the_dtypes(dtypes):
    # float64/int64 answers go through the compiled check, the others through numpy: both take the same answers
    from evoscen_sim.model_registry import _fine

    f, i = dtypes
    good = (np.array([0.5, -1.0, 0.0], dtype=f), np.array([1, -1, 0], dtype=i))
    assert _fine(*good, 3) and _fine(*good, None) and not _fine(*good, 2)
    assert _fine(np.zeros(0, dtype=f), np.zeros(0, dtype=i), 0)
    for k in range(3):  # one bad entry anywhere is refused
        for bad in (np.nan, np.inf, -np.inf):
            t = good[0].copy()
            t[k] = bad
            assert not _fine(t, good[1], 3)
        for bad in (2, -2):
            lc = good[1].copy()
            lc[k] = bad
            assert not _fine(good[0], lc, 3)
    assert not _fine(good[0], good[1].astype(float), 3)  # lane changes must be integers
    assert not _fine(good[0].reshape(3, 1), good[1].reshape(3, 1), 3)


@pytest.fixture(scope="module")
def bad_package(tmp_path_factory, pip_install_into) -> Path:
    """A package with a BadDriver SUT ('nan' from step 3) behind an entry point, pip-installed into a directory."""
    src = tmp_path_factory.mktemp("bad_sut")
    (src / "pyproject.toml").write_text(
        '[build-system]\nrequires = ["setuptools>=64"]\nbuild-backend = "setuptools.build_meta"\n'
        '[project]\nname = "evoscen-bad-sut"\nversion = "0"\n'
        '[project.entry-points."evoscen.sut"]\nbad_sut = "bad_sut:SPEC"\n[tool.setuptools]\npy-modules = ["bad_sut"]\n',
        encoding="utf-8")
    import inspect

    (src / "bad_sut.py").write_text(
        "import numpy as np\nfrom evoscen_sim.model_registry import ModelSpec\n\n" + inspect.getsource(BadDriver)
        + "\n\nSPEC = ModelSpec(name='bad_sut', roles=('sut',), factory=lambda v, p, c, r: BadDriver(v, 'nan'))\n",
        encoding="utf-8")
    return pip_install_into(src)


@pytest.mark.e2e  # a node graph in a subprocess
def test_a_bad_answer_in_the_node_graph_is_one_error_line_naming_the_model(bad_package, env_with_path, tmp_path):
    res = run_cli("--mode", "graph", "--sut", "bad_sut", "--steps", 20, "--no-plots", "--quiet",
                  "--out", tmp_path / "out", env=env_with_path(bad_package))
    errors = [line for line in res.stderr.splitlines() if line.startswith("error: ")]
    assert res.returncode == 2 and "Traceback" not in res.stderr, (res.returncode, res.stderr)
    # the in-process runner's line, naming the graph's node logs
    assert errors == [f"error: sut model 'bad_sut': {BAD['nan']} (node logs: {tmp_path / 'out' / 'logs'}/)"], res.stderr


def test_a_bad_bv_answer_is_one_line_before_anything_is_written(tmp_path, capsys):
    """A BV model's answer is checked already in the warm-up (before the output directory is touched)."""
    import run_scenario
    from evoscen_sim.model_registry import ModelSpec, register_model, unregister_model

    class ShortBv:
        def __init__(self, vehicles) -> None:
            self.n = len(vehicles)

        def act(self, view):
            return np.zeros(self.n - 1), np.zeros(self.n - 1, dtype=np.int64)

    config = tmp_path / "scenario.yaml"
    config.write_text("bvs: {driver: short_bv, makeup: uniform}\n", encoding="utf-8")
    register_model(ModelSpec(name="short_bv", roles=("bv",), factory=lambda v, p, c, r: ShortBv(v)))
    try:
        code = run_scenario.main(["--mode", "inprocess", "--config", str(config), "--steps", "20", "--quiet",
                                  "--out", str(tmp_path / "out")])
    finally:
        unregister_model("short_bv")
    line = one_error_line(capsys.readouterr().err)
    assert code == 2 and line == ("error: bv model 'short_bv': act() returned a throttle of shape (19,); "
                                  "expected shape (20,), one per vehicle"), line
    assert not (tmp_path / "out").exists()


def test_the_launcher_reports_a_refused_answer_before_the_deadline_fault_it_causes():
    from evoscen_bringup.graph_runner import graph_status
    from evoscen_contract.contract import (
        EXIT_BAD_INPUT,
        EXIT_FAULT,
        EXIT_INTERRUPTED,
        NODE_BV,
        NODE_EVAL,
        NODE_SIM,
        NODE_SUT,
    )

    nodes = {NODE_SIM: EXIT_FAULT, NODE_EVAL: 0, NODE_BV: 0, NODE_SUT: EXIT_BAD_INPUT}
    assert graph_status(nodes, {NODE_SUT: "refused its driver's answer"}, False) == EXIT_BAD_INPUT
    assert graph_status({**nodes, NODE_SIM: EXIT_INTERRUPTED}, {}, False) == EXIT_BAD_INPUT
    assert graph_status({**nodes, NODE_SUT: 0}, {}, False) == EXIT_FAULT  # a fault of its own stays 3
