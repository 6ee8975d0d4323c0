"""The "your first SUT" walk-through (docs/plugins.md §2) is code that runs.

* ``examples/first_sut/first_sut.py`` decides as the walk-through says, in situations built by hand
  (:func:`evoscen_sim.loop.hand_built.hand_built_world`);
* registered in this process (:func:`evoscen_sim.model_registry.register_model`) it is the SUT of an
  in-process run started as ``run_scenario.py --sut first_sut``, and a bad ``models.first_sut``
  parameter is one line naming it;
* installed from its ``pyproject.toml`` (into a temporary directory, never into the checkout's
  ``.venv``) its entry point is found by the command line, and the node graph and the in-process
  runner write the same bag (e2e);
* the code blocks of docs/plugins.md that quote a file are that file, and the walk-through
  shows all of ``first_sut.py``; the signatures and names the page lists are the code's.
"""

from __future__ import annotations

import inspect
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
EXAMPLE = REPO / "examples" / "first_sut"
DOC = REPO / "docs" / "plugins.md"
sys.path.insert(0, str(REPO / "scripts"))

MARKER = re.compile(r"^\s*# --8<-- \[(start|end):([a-z_]+)\]\s*$")
INCLUDE = re.compile(r"<!-- include: (?P<path>[^#\s,]+)(?:#(?P<region>[a-z_]+))?(?P<dedented>, dedented)? -->\n"
                     r"```[a-z]*\n(?P<body>.*?)```", re.S)


@pytest.fixture(scope="module")
def fs(load_example):
    return load_example("first_sut")


@pytest.fixture(scope="module")
def cfg():
    from evoscen_sim.config.scenario_config import load_scenario_config

    return load_scenario_config(None, {})


@pytest.fixture(scope="module")
def road():
    from evoscen_sim.road.road_model import load_road

    return load_road()


def sut_driver(fs, cfg, **params):
    """The first SUT driving vehicle 0, with ``params`` overriding its defaults."""
    return fs.make(np.array([0]), fs.FirstSutParams(**params), cfg, np.random.default_rng(0))


def decide(fs, cfg, road, s, lane, speed, **params) -> tuple[float, int]:
    """(throttle, request) of the SUT (vehicle 0) in a hand-built world; the others are BVs."""
    from evoscen_sim.loop.hand_built import hand_built_world

    world = hand_built_world(road, s=s, lane=lane, speed=speed, roles=[1] + [0] * (len(s) - 1))
    throttle, request = sut_driver(fs, cfg, **params).act(world)
    assert throttle.shape == (1,) and request.shape == (1,) and -1.0 <= throttle[0] <= 1.0
    return float(throttle[0]), int(request[0])


# ------------------------------------------------------------------ situations built by hand


def test_slow_leader_and_free_left_lane_requests_left(fs, cfg):
    # --8<-- [start:hand_built]
    import first_sut
    import numpy as np
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sim.loop.hand_built import hand_built_world
    from evoscen_sim.road.road_model import load_road

    road = load_road()  # the shipped on-ramp map
    config = load_scenario_config()  # the shipped scenario: vehicle limits, dt_s
    sut = first_sut.make(np.array([0]), first_sut.FirstSutParams(), config, np.random.default_rng(0))

    # the SUT (vehicle 0) at 28 m/s in lane 2, a leader at 20 m/s 30 m ahead, lane 3 empty
    world = hand_built_world(road, s=[300, 330], lane=[2, 2], speed=[28, 20], roles=[1, 0])
    throttle, lane_change = sut.act(world)
    assert lane_change.tolist() == [1] and throttle[0] < 0  # brakes for the leader, asks to go left

    # the same, and a follower in lane 3, 15 m behind, closing at 36 m/s: it waits
    world = hand_built_world(road, s=[300, 330, 280], lane=[2, 2, 3], speed=[28, 20, 36], roles=[1, 0, 0])
    throttle, lane_change = sut.act(world)
    assert lane_change.tolist() == [0]
    # --8<-- [end:hand_built]
    assert first_sut is fs


def test_follower_closing_fast_in_the_target_lane_waits(fs, cfg, road):
    # the follower 15.2 m behind (bumper to bumper): enough at the SUT's speed (10 m + 2 s x 0 m/s)...
    assert decide(fs, cfg, road, [300, 330, 280], [2, 2, 3], [28, 20, 28])[1] == 1
    # ...not when it closes at 8 m/s (10 m + 2 s x 8 m/s = 26 m)
    assert decide(fs, cfg, road, [300, 330, 280], [2, 2, 3], [28, 20, 36])[1] == 0
    # a leader in the left lane too close ahead (15.2 m < 20 m): waits
    assert decide(fs, cfg, road, [300, 330, 320], [2, 2, 3], [28, 20, 28])[1] == 0


def test_keeps_lane_without_a_slow_leader_within_reach(fs, cfg, road):
    throttle, request = decide(fs, cfg, road, [300], [2], [28])  # free road, below 30 m/s: speeds up
    assert request == 0 and throttle > 0
    assert decide(fs, cfg, road, [300, 330], [2, 2], [28, 28])[1] == 0  # leader not slower than 27 m/s
    assert decide(fs, cfg, road, [300, 420], [2, 2], [28, 20])[1] == 0  # slow leader beyond 80 m
    assert decide(fs, cfg, road, [300, 420], [2, 2], [28, 20], look_ahead_m=150.0)[1] == 1
    assert decide(fs, cfg, road, [300, 330], [4, 4], [28, 20])[1] == 0  # lane 4 is the leftmost


def test_merge_lane_is_left_as_soon_as_the_left_lane_is_free(fs, cfg, road):
    assert decide(fs, cfg, road, [700], [0], [22])[1] == 1  # lane 0 ends at 960 m: no slow leader needed
    throttle, request = decide(fs, cfg, road, [900, 900], [0, 1], [22, 22])  # a vehicle beside it
    assert request == 0 and throttle == -1.0  # waits, braking for the lane's end 60 m ahead


def drive(world, sut, steps: int) -> list:
    """Step ``world`` with ``sut`` driving vehicle 0, the others holding their speed; the StepResults."""
    results = []
    for _ in range(steps):
        throttle = np.zeros(world.n)
        request = np.zeros(world.n, dtype=np.int64)
        throttle[0], request[0] = (a[0] for a in sut.act(world))
        results.append(world.step(throttle, request))
    return results


def test_blocked_on_the_merge_lane_it_stops_before_the_end_then_merges(fs, cfg, road):
    from evoscen_sim.loop.hand_built import hand_built_world

    wall = np.arange(600.0, 1000.0, 10.0)  # lane 1 full of standing vehicles: never a gap
    world = hand_built_world(road, s=[700.0, *wall], lane=[0] + [1] * wall.size, speed=[22.0] + [0.0] * wall.size,
                             roles=[1] + [0] * wall.size)
    sut = sut_driver(fs, cfg)
    results = drive(world, sut, 400)
    assert not any(0 in r.off_road for r in results) and not any(r.executed_lane_change[0] for r in results)
    assert world.lane[0] == 0 and world.v[0] < 0.01
    assert 930.0 < world.s[0] < road.lane_end_s[0] - fs.FirstSutParams().lane_end_margin_m  # stopped short of 945 m
    world.s[1:] += 2000.0  # the wall gone
    world.refresh()
    results = drive(world, sut, 200)
    assert [(f, t) for r in results for i, f, t, _ in r.lane_changes_completed if i == 0] == [(0, 1)]
    assert not any(0 in r.off_road for r in results) and world.lane[0] == 1


def test_a_vehicle_changing_into_the_same_lane_from_two_lanes_over_blocks(fs, cfg, road):
    from evoscen_sim.loop.hand_built import hand_built_world

    world = hand_built_world(road, s=[300, 330, 305], lane=[2, 2, 4], speed=[28, 20, 28], roles=[1, 0, 0])
    assert sut_driver(fs, cfg).act(world)[1].tolist() == [1]  # lane 4's vehicle keeps its lane
    world.lane_change[2], world.target_lane[2] = -1, 3  # it is changing into lane 3
    assert sut_driver(fs, cfg).act(world)[1].tolist() == [0]


def test_decides_again_only_once_settled_after_a_change(fs, cfg, road):
    """Slow leaders in lanes 2 and 3: 2 -> 3, then 3 -> 4; no request during a change, and the
    second only once the SUT is within settle_tolerance_m of lane 3's centre line (not at the
    completion, when its centre has just crossed the line)."""
    from evoscen_sim.loop.hand_built import hand_built_world

    world = hand_built_world(road, s=[300, 340, 360], lane=[2, 2, 3], speed=[25, 20, 20], roles=[1, 0, 0])
    sut = sut_driver(fs, cfg)
    tol = fs.FirstSutParams().settle_tolerance_m
    executed, completed = [], []
    for k in range(150):
        changing, lane = int(world.lane_change[0]), int(world.lane[0])
        off_centre = abs(world.d[0] - road.lane_center_d(lane, world.s[0]))
        throttle = np.zeros(world.n)
        request = np.zeros(world.n, dtype=np.int64)
        throttle[0], request[0] = (a[0] for a in sut.act(world))
        if request[0]:
            assert changing == 0 and off_centre <= tol, (k, changing, off_centre)
        result = world.step(throttle, request)
        if result.executed_lane_change[0]:
            executed.append((k, lane, int(result.executed_lane_change[0])))
        completed += [(k, f, t) for i, f, t, _ in result.lane_changes_completed if i == 0]
    assert [(lane, r) for _, lane, r in executed] == [(2, 1), (3, 1)]
    assert [(f, t) for _, f, t in completed] == [(2, 3), (3, 4)]
    # between the first completion and the second request: settling (about 2.7 s at 20 m/s)
    assert executed[1][0] - completed[0][0] > 10, (executed, completed)


# ------------------------------------------------------------------ registered in this process


@pytest.fixture
def registered(fs):
    from evoscen_sim.model_registry import register_model, unregister_model

    register_model(fs.SPEC)
    yield fs
    unregister_model(fs.SPEC.name)


def test_registered_model_is_the_sut_of_an_in_process_run(registered, tmp_path, monkeypatch, capsys):
    import run_scenario

    calls = []
    act = registered.FirstSut.act

    def counted(self, view):
        calls.append(view.step_index)
        return act(self, view)

    monkeypatch.setattr(registered.FirstSut, "act", counted)
    out = tmp_path / "out"
    code = run_scenario.main(["--mode", "inprocess", "--sut", "first_sut", "--steps", "150", "--seed", "1",
                              "--no-record", "--no-plots", "--quiet", "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "steps: 150" in captured.out
    assert calls == list(range(150))  # asked once per step, from step 0 (after the warm-up)
    assert "model: first_sut" in (out / "scenario.yaml").read_text(encoding="utf-8")


def one_error_line(stderr: str) -> str:
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in stderr, stderr
    return lines[0]


@pytest.mark.parametrize(("value", "expected"), [
    ("-3", "key 'models.first_sut.slow_leader_mps' = -3: expected a number in [0, 40] (line 3)"),
    ("fast", "key 'models.first_sut.slow_leader_mps' = 'fast': expected a number in [0, 40] (line 3)"),
    ("true", "key 'models.first_sut.slow_leader_mps' = True: expected a number in [0, 40] (line 3)"),
])
def test_bad_parameter_is_one_line_naming_the_plugin(registered, tmp_path, capsys, value, expected):
    import run_scenario

    config = tmp_path / "scenario.yaml"
    config.write_text(f"sut: {{model: first_sut}}\nmodels:\n  first_sut: {{slow_leader_mps: {value}}}\n",
                      encoding="utf-8")
    code = run_scenario.main(["--mode", "inprocess", "--config", str(config), "--steps", "10", "--no-record",
                              "--quiet", "--out", str(tmp_path / "out")])
    line = one_error_line(capsys.readouterr().err)
    assert code == 2 and line == f"error: {config}: {expected}", line
    assert not (tmp_path / "out").exists()  # nothing written before the input is valid


def test_unknown_parameter_names_the_plugin_and_suggests(registered):
    from evoscen_sim.config.scenario_config import config_from_dict
    from evoscen_sim.errors import InputError

    with pytest.raises(InputError) as err:
        config_from_dict({"models": {"first_sut": {"slow_leader": 20}}}, source="s.yaml")
    text = str(err.value)
    assert "\n" not in text and text.startswith("s.yaml: key 'models.first_sut.slow_leader': unknown key")
    assert text.endswith("did you mean 'slow_leader_mps'?"), text


# ------------------------------------------------------------------ installed from pyproject.toml


@pytest.fixture(scope="module")
def installed(pip_install_into) -> Path:
    """The example pip-installed into a directory of its own (a copy is built: the source tree stays clean)."""
    return pip_install_into(EXAMPLE)


@pytest.fixture(scope="module")
def run_cli(installed, env_with_path):
    """``run_cli(*args)``: ``run_scenario.py`` as a subprocess that finds the installed example."""
    env = env_with_path(installed)

    def run(*args: object) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "scripts/run_scenario.py", *map(str, args)], cwd=REPO, env=env,
                              capture_output=True, text=True, timeout=300, check=False)
    return run


@pytest.mark.e2e  # pip-installs the example, runs the CLI and a node graph as subprocesses
def test_installed_example_runs_in_both_runners_with_the_same_bag(installed, run_cli, tmp_path):
    info = next(installed.glob("evoscen_first_sut-*.dist-info"))
    assert "[evoscen.sut]\nfirst_sut = first_sut:SPEC" in (info / "entry_points.txt").read_text(encoding="utf-8")
    runs = {}
    for mode in ("graph", "inprocess"):
        res = run_cli("--mode", mode, "--sut", "first_sut", "--steps", 60, "--seed", 2, "--no-plots", "--quiet",
                      "--out", tmp_path / mode)
        assert res.returncode == 0, (mode, res.stdout, res.stderr)
        runs[mode] = (tmp_path / mode / "bag" / "bag_0.mcap").read_bytes()
    assert runs["graph"] == runs["inprocess"]


@pytest.mark.e2e  # runs the CLI as a subprocess
def test_installed_example_bad_parameter_is_one_line(run_cli, tmp_path):
    config = tmp_path / "scenario.yaml"
    config.write_text("models:\n  first_sut:\n    settle_tolerance_m: 2.5\n", encoding="utf-8")
    res = run_cli("--mode", "inprocess", "--config", config, "--sut", "first_sut", "--no-record", "--quiet",
                  "--out", tmp_path / "out")
    line = one_error_line(res.stderr)
    assert res.returncode == 2
    assert line == (f"error: {config}: key 'models.first_sut.settle_tolerance_m' = 2.5: "
                    "expected a number in [0, 1.75] (line 3)"), line


# ------------------------------------------------------------------ the page and the code agree


def regions(path: Path) -> dict[str, str]:
    """The ``# --8<-- [start:NAME]`` ... ``[end:NAME]`` regions of a file (marker lines left out)."""
    out: dict[str, list[str]] = {}
    open_name = None
    for line in path.read_text(encoding="utf-8").splitlines():
        m = MARKER.match(line)
        if m is None:
            if open_name is not None:
                out[open_name].append(line)
            continue
        kind, name = m.groups()
        if kind == "start":
            assert open_name is None and name not in out, f"{path}: region {name} opened twice or nested"
            out[name], open_name = [], name
        else:
            assert open_name == name, f"{path}: region {name} closed but {open_name} is open"
            open_name = None
    assert open_name is None, f"{path}: region {open_name} not closed"
    return {name: "\n".join(lines) + "\n" for name, lines in out.items()}


def doc_includes() -> list[tuple[str, str | None, str]]:
    """(path, region or None, the code block under it, dedented?) for every ``<!-- include: ... -->``
    of the page (``<!-- include: PATH#REGION, dedented -->``: the region with its common indentation removed)."""
    return [(m["path"], m["region"], m["body"], bool(m["dedented"]))
            for m in INCLUDE.finditer(DOC.read_text(encoding="utf-8"))]


def test_doc_code_blocks_are_the_files():
    included = doc_includes()
    assert included, "docs/plugins.md quotes no file"
    for path, region, body, dedented in included:
        file = REPO / path
        expected = file.read_text(encoding="utf-8") if region is None else regions(file)[region]
        if dedented:
            expected = textwrap.dedent(expected)
        assert body == expected, f"docs/plugins.md: the block under 'include: {path}#{region}' differs from the file"


def test_walk_through_shows_all_of_the_example():
    shown = [region for path, region, _, dedented in doc_includes()
             if path == "examples/first_sut/first_sut.py" and not dedented]
    code = EXAMPLE / "first_sut.py"
    assert sorted(shown) == sorted(regions(code)), "every region of first_sut.py is quoted once in docs/plugins.md"
    inside = {line for text in regions(code).values() for line in text.splitlines()}
    outside = [line for line in code.read_text(encoding="utf-8").splitlines()
               if line.strip() and not MARKER.match(line) and line not in inside]
    assert not outside, f"lines of first_sut.py in no region (not in the walk-through): {outside}"
    assert any(path == "examples/first_sut/pyproject.toml" and region is None for path, region, _, _ in doc_includes())


def test_doc_lists_the_declarators_with_their_signatures():
    from evoscen_sim.config import config_checks

    text = DOC.read_text(encoding="utf-8")
    block = text.split("<!-- signatures: evoscen_sim.config.config_checks -->\n```python\n", 1)[1].split("```", 1)[0]
    listed = [line for line in block.splitlines() if line and not line.startswith("#")]
    names = ("number", "integer", "flag", "text", "number_range", "names")
    expected = []
    for name in names:
        sig = inspect.signature(getattr(config_checks, name)).replace(return_annotation=inspect.Signature.empty)
        expected.append(name + str(sig).replace("'", ""))
    assert listed == expected


def test_doc_names_every_view_attribute_and_road_query():
    from evoscen_sim.loop.view import TrafficView
    from evoscen_sim.road.road_model import RoadModel

    text = DOC.read_text(encoding="utf-8")
    view = [n for n in dir(TrafficView) if not n.startswith("_")] + list(TrafficView.__annotations__)
    road = [n for n, _ in inspect.getmembers(RoadModel, inspect.isfunction) if not n.startswith("_")]
    road += ["length_m", "num_lanes", "lane_ids", "lane_start_s", "lane_end_s", "lane_full_width_end_s",
             "lane_width_m", "map"]
    missing = sorted({n for n in view + road if f"`{n}" not in text})
    assert not missing, f"docs/plugins.md does not name: {missing}"
