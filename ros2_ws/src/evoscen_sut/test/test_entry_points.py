"""The plug-in route: a user's own SUT model, registered through an entry point of group
``evoscen.sut``, runs without any change to evoscen.

The user's "installed package" is a directory on PYTHONPATH holding the module
``my_sut_plugin.py`` (a ``SPEC = ModelSpec(...)``) and a ``my_sut_plugin-0.1.dist-info/``
(``METADATA`` + ``entry_points.txt``), which is all ``importlib.metadata`` needs. Every run is
a subprocess, so the plug-in never leaks into this process's model registry.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[4]
SCRIPT = REPO / "scripts" / "run_scenario.py"

PLUGIN = textwrap.dedent('''
    """A user's SUT model: proportional speed control towards a desired speed, no lane changes."""
    from dataclasses import dataclass

    import numpy as np

    from evoscen_sim.config.scenario_config import number
    from evoscen_sim.model_registry import ModelSpec
    from evoscen_sim.physics.vehicle import accel_to_throttle


    @dataclass(frozen=True)
    class MySutParams:
        desired_speed_mps: float = number(25.0, 0.0, 40.0, lo_open=True)
        """Desired speed (m/s); example default."""
        gain_per_s: float = number(0.5, 0.0, 5.0, lo_open=True)
        """Acceleration per m/s of speed error (1/s); example default."""


    class MySut:
        def __init__(self, vehicles, params, config, rng):
            self.vehicles, self.params = vehicles, params
            self.vehicle = config.vehicle
            self.calls = 0

        def act(self, view):
            self.calls += 1
            v = np.asarray(view.v)[self.vehicles]
            accel = self.params.gain_per_s * (self.params.desired_speed_mps - v)
            return accel_to_throttle(accel, self.vehicle), np.zeros(len(self.vehicles), dtype=np.int64)


    def make(vehicles, params, config, rng):
        return MySut(vehicles, params, config, rng)


    SPEC = ModelSpec(name="my_sut", roles=("sut",), factory=make, params_type=MySutParams,
                     description="a user's plug-in SUT (test)")
    NOT_A_SPEC = {"name": "broken"}
    CLASH = ModelSpec(name="mobil", roles=("sut",), factory=make, params_type=MySutParams, description="clash")
    KRAUSS = ModelSpec(name="krauss", roles=("sut",), factory=make, params_type=MySutParams, description="clash")


    @dataclass(frozen=True)
    class PlainParams:
        gain: float = 0.5


    PLAIN = ModelSpec(name="plain_sut", roles=("sut",), factory=make, params_type=PlainParams, description="plain")
''')

RUN_INPROCESS = textwrap.dedent('''
    import sys
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_bringup.scenario import build_scenario
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sim.errors import InputError

    try:
        cfg = load_scenario_config(sys.argv[1], {})
        sc = build_scenario(cfg)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(2)
    summary = run_inprocess(cfg, bag_dir=None, scenario=sc)
    print(type(sc.sut).__module__, type(sc.sut).__name__, sc.sut.calls, summary.steps,
          sc.sut.params.desired_speed_mps, repr(float(sc.world.v[sc.sut_index])), summary.collisions)
''')


def make_plugin_dir(root: Path, entry_points: str) -> Path:
    """``root`` with the plug-in module and a dist-info declaring ``entry_points``."""
    root.mkdir(parents=True, exist_ok=True)
    (root / "my_sut_plugin.py").write_text(PLUGIN, encoding="utf-8")
    info = root / "my_sut_plugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: my_sut_plugin\nVersion: 0.1\n", encoding="utf-8")
    (info / "entry_points.txt").write_text(entry_points, encoding="utf-8")
    return root


def write_config(path: Path, models: dict) -> Path:
    path.write_text(yaml.safe_dump({"steps": 100, "seed": 4, "sut": {"model": "my_sut"}, "models": models}),
                    encoding="utf-8")
    return path


def run(argv: list[str], plugin_dir: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    # the plug-in's directory first, then what this process imports evoscen from
    env["PYTHONPATH"] = os.pathsep.join([str(plugin_dir), *(p for p in sys.path if p)])
    return subprocess.run([sys.executable, *argv], env=env, cwd=REPO, capture_output=True, text=True,
                          timeout=120, check=False)


def one_line_error(res: subprocess.CompletedProcess) -> str:
    assert "Traceback" not in res.stderr, res.stderr
    assert res.returncode == 2, (res.returncode, res.stdout, res.stderr)
    lines = [line for line in res.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), res.stderr
    return lines[0]


@pytest.fixture
def plugin(tmp_path: Path) -> Path:
    return make_plugin_dir(tmp_path / "site", "[evoscen.sut]\nmy_sut = my_sut_plugin:SPEC\n")


def test_plugin_drives_the_sut_in_process(plugin: Path, tmp_path: Path) -> None:
    cfg = write_config(tmp_path / "scenario.yaml", {"my_sut": {"desired_speed_mps": 20.0}})
    res = run(["-c", RUN_INPROCESS, str(cfg)], plugin)
    assert res.returncode == 0, res.stderr
    module, cls, calls, steps, desired, speed, collisions = res.stdout.split()
    assert (module, cls, int(calls), int(steps)) == ("my_sut_plugin", "MySut", 100, 100)
    assert float(desired) == 20.0  # models.my_sut from the YAML reached the model
    # from 27 m/s, 10 s of a = 0.5 (20 - v) (at most 8 m/s² of braking): v = 20 + 7 e^-5 = 20.05
    assert abs(float(speed) - 20.0) < 0.2, speed


@pytest.mark.e2e  # runs a CLI as a subprocess
def test_plugin_through_the_cli(plugin: Path, tmp_path: Path) -> None:
    cfg = write_config(tmp_path / "scenario.yaml", {"my_sut": {"gain_per_s": 1.0}})
    res = run([str(SCRIPT), "--mode", "inprocess", "--config", str(cfg), "--sut", "my_sut", "--no-record",
               "--quiet", "--out", str(tmp_path / "out")], plugin)
    assert res.returncode == 0, res.stderr
    assert "steps: 100" in res.stdout
    assert (tmp_path / "out" / "scenario.yaml").read_text(encoding="utf-8").count("my_sut") >= 2


@pytest.mark.e2e  # runs a CLI as a subprocess
def test_bad_plugin_parameter_is_a_one_line_error(plugin: Path, tmp_path: Path) -> None:
    cfg = write_config(tmp_path / "scenario.yaml", {"my_sut": {"gain_per_s": -1.0}})
    line = one_line_error(run([str(SCRIPT), "--mode", "inprocess", "--config", str(cfg), "--no-record", "--quiet",
                               "--out", str(tmp_path / "out")], plugin))
    assert "models.my_sut.gain_per_s" in line and "-1" in line and str(cfg) in line, line
    assert not (tmp_path / "out").exists()  # nothing touched before the input is valid


@pytest.mark.parametrize(("key", "value"), [("desired_speed_mps", "fast"), ("gain", 1.0)])
def test_bad_plugin_parameter_in_process(plugin: Path, tmp_path: Path, key: str, value: object) -> None:
    """A value of the wrong type, an unknown key: named the same way."""
    cfg = write_config(tmp_path / "scenario.yaml", {"my_sut": {key: value}})
    line = one_line_error(run(["-c", RUN_INPROCESS, str(cfg)], plugin))
    assert f"models.my_sut.{key}" in line, line


@pytest.mark.parametrize(("value", "needle", "via_cli"), [
    pytest.param("my_sut_plugin:NOT_A_SPEC", "is not an evoscen.ModelSpec (got dict)", True,
                 marks=pytest.mark.e2e),  # through the CLI
    ("my_sut_plugin:MISSING", "failed to load: AttributeError: module 'my_sut_plugin' has no attribute 'MISSING'", False),
    ("no_such_module:SPEC", "failed to load: ModuleNotFoundError: No module named 'no_such_module'", False),
])
def test_broken_entry_point_fails_only_the_run_that_selects_it(tmp_path: Path, value: str, needle: str,
                                                               via_cli: bool) -> None:
    """A broken entry point beside a working one (docs/plugins.md §3): the working one runs, with one
    warning naming the broken one and why; a run that selects the broken one fails with that line."""
    plugin = make_plugin_dir(tmp_path / "site", f"[evoscen.sut]\nmy_sut = my_sut_plugin:SPEC\nbroken = {value}\n")
    problem = f"entry point 'broken' in group 'evoscen.sut' ({value}) {needle}"
    cfg = write_config(tmp_path / "scenario.yaml", {})
    ok = run(["-c", RUN_INPROCESS, str(cfg)], plugin)
    assert ok.returncode == 0, ok.stderr
    assert ok.stdout.split()[:2] == ["my_sut_plugin", "MySut"], ok.stdout  # the working plug-in drove the SUT
    assert [line for line in ok.stderr.splitlines() if "entry point" in line] == [f"warning: {problem}"], ok.stderr
    selected = write_config(tmp_path / "broken.yaml", {})
    selected.write_text(selected.read_text(encoding="utf-8").replace("model: my_sut", "model: broken"), encoding="utf-8")
    argv = ([str(SCRIPT), "--mode", "inprocess", "--steps", "10", "--no-record", "--quiet", "--sut", "broken",
             "--out", str(tmp_path / "out")] if via_cli else ["-c", RUN_INPROCESS, str(selected)])
    line = one_line_error(run(argv, plugin))
    where = "command line" if via_cli else str(selected)
    assert line.startswith(f"error: {where}: key 'sut.model' = 'broken': {problem}"), line


@pytest.mark.parametrize("name, taken", [("CLASH", "a built-in model"), ("KRAUSS", "the parameter set models.krauss")])
def test_a_plugin_named_like_a_builtin_or_a_parameter_set_is_one_line(tmp_path: Path, name: str, taken: str) -> None:
    site = make_plugin_dir(tmp_path / "site", f"[evoscen.sut]\nclash = my_sut_plugin:{name}\n")
    cfg = tmp_path / "scenario.yaml"
    cfg.write_text(yaml.safe_dump({"steps": 10, "sut": {"model": "clash"}}), encoding="utf-8")
    line = one_line_error(run(["-c", RUN_INPROCESS, str(cfg)], site))
    assert f"entry point 'clash' in group 'evoscen.sut' (my_sut_plugin:{name}) registers the model" in line
    assert f"the name of {taken}: give the plug-in's model another name" in line


def test_a_parameter_field_without_a_declarator_is_one_line(tmp_path: Path) -> None:
    site = make_plugin_dir(tmp_path / "site", "[evoscen.sut]\nplain_sut = my_sut_plugin:PLAIN\n")
    cfg = tmp_path / "scenario.yaml"
    cfg.write_text(yaml.safe_dump({"steps": 10, "sut": {"model": "plain_sut"}, "models": {"plain_sut": {"gain": 1.0}}}),
                   encoding="utf-8")
    line = one_line_error(run(["-c", RUN_INPROCESS, str(cfg)], site))
    assert "key 'models.plain_sut.gain' = 1.0" in line
    assert "my_sut_plugin.PlainParams.gain has no declarator, so it cannot be set" in line
