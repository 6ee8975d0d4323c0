"""The layout of the packages keeps what docs/architecture.md §1 ("Module map") says of it.

* The ground floor of ``evoscen_sim`` (``errors``, ``limits``, ``jit``) imports nothing else of
  evoscen but itself, and the package's ``__init__`` only the standard-library ``moved_paths``.
* The paths the rooms replaced still import, as aliases of the new modules, with one
  DeprecationWarning naming the new path.

Read statically with :mod:`ast` (the import graph of tests/test_import_cycles.py); nothing here
starts a simulation.
"""

from __future__ import annotations

import importlib
import sys
import warnings
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the import graph of the cycle test
from test_import_cycles import SRC, find_cycles, import_graph, project_modules

GROUND_FLOOR = ("evoscen_sim.errors", "evoscen_sim.limits", "evoscen_sim.jit")


def test_the_ground_floor_imports_nothing_else_of_evoscen() -> None:
    graph = import_graph(project_modules())
    for name in GROUND_FLOOR:
        assert name in graph, name
    upward = sorted(f"{name} -> {target}" for name in GROUND_FLOOR for target in graph[name]
                    if target not in GROUND_FLOOR)
    assert upward == [], "the ground floor imports from above it: " + "; ".join(upward)
    # limits raises the one error type; errors and jit import nothing of evoscen
    assert graph["evoscen_sim.limits"] == {"evoscen_sim.errors"}
    assert graph["evoscen_sim.errors"] == set() and graph["evoscen_sim.jit"] == set()
    assert graph["evoscen_sim"] == {"evoscen_sim.moved_paths"} and graph["evoscen_sim.moved_paths"] == set()


PACKAGE_IMPORTS = {
    "evoscen_contract": (),
    "evoscen_sim": ("evoscen_contract",),
    "evoscen_sut": ("evoscen_contract", "evoscen_sim"),
    "evoscen_bv": ("evoscen_contract", "evoscen_sim", "evoscen_sut"),
    "evoscen_record": ("evoscen_contract", "evoscen_sim"),
    "evoscen_eval": ("evoscen_contract", "evoscen_sim", "evoscen_record"),
    "evoscen_bringup": ("evoscen_contract", "evoscen_sim", "evoscen_sut", "evoscen_bv", "evoscen_record", "evoscen_eval"),
    "evoscen_experiments": ("evoscen_contract", "evoscen_sim", "evoscen_sut", "evoscen_bv", "evoscen_record",
                            "evoscen_eval", "evoscen_bringup"),
    "evoscen": ("evoscen_contract", "evoscen_sim", "evoscen_sut", "evoscen_bv", "evoscen_record", "evoscen_eval",
                "evoscen_bringup", "evoscen_experiments"),
}
"""What each package may import (docs/architecture.md §1), from the bottom: the contract; the simulation;
the SUT models; the BV drivers (they follow like SUTs); the recording; the evaluation; the runners; the
experiments; the face, which may import everything."""

_BELOW = ("evoscen_contract", "evoscen_sim.errors", "evoscen_sim.limits", "evoscen_sim.jit", "evoscen_sim.moved_paths",
          "evoscen_sim.config", "evoscen_sim.road")
_BELOW_EVAL = ("evoscen_contract", "evoscen_sim", "evoscen_record")
ROOM_IMPORTS = {
    "evoscen_sim.config": ("evoscen_contract", "evoscen_sim.errors", "evoscen_sim.limits", "evoscen_sim.moved_paths",
                           "evoscen_sim.model_registry", "evoscen_sim.share", "evoscen_sim.config"),
    "evoscen_sim.road": ("evoscen_contract", "evoscen_sim.errors", "evoscen_sim.limits", "evoscen_sim.jit",
                         "evoscen_sim.share", "evoscen_sim.config", "evoscen_sim.road"),
    "evoscen_sim.physics": (*_BELOW, "evoscen_sim.physics"),
    "evoscen_sim.traffic": (*_BELOW, "evoscen_sim.physics", "evoscen_sim.traffic"),
    "evoscen_sim.danger": (*_BELOW, "evoscen_sim.physics", "evoscen_sim.danger"),
    "evoscen_sim.loop": (*_BELOW, "evoscen_sim.physics", "evoscen_sim.traffic", "evoscen_sim.danger", "evoscen_sim.loop"),
    "evoscen_sim.nodes": ("evoscen_contract", "evoscen_sim"),
    "evoscen_eval.scoring": (*_BELOW_EVAL, "evoscen_eval.scoring"),
    "evoscen_eval.naturalistic": (*_BELOW_EVAL, "evoscen_eval.scoring", "evoscen_eval.naturalistic"),
    "evoscen_eval.scenes": (*_BELOW_EVAL, "evoscen_eval.scoring", "evoscen_eval.scenes"),
}
"""What each room may import (docs/architecture.md §1, module map). In evoscen_sim: the ground floor, the
contract, the configuration and the road below every room; physics (the world and the traffic window its
step runs) nothing above them; traffic and danger physics; the loop any room; the nodes anything of the
simulation. In evoscen_eval: scoring the packages below evoscen_eval only; naturalistic and scenes the
scoring room. Every sub-package of every package is a room here."""


def _package_of(module: str) -> str:
    return module.split(".")[0]


def test_each_package_imports_only_the_packages_below_it() -> None:
    graph = import_graph(project_modules())
    packages = {p.name for p in SRC.iterdir() if (p / p.name / "__init__.py").is_file()}
    assert packages == set(PACKAGE_IMPORTS), "every package has its place in PACKAGE_IMPORTS"
    wrong = sorted(f"{name} -> {target}" for name, targets in graph.items() for target in targets
                   if _package_of(target) != _package_of(name)
                   and _package_of(target) not in PACKAGE_IMPORTS[_package_of(name)])
    assert wrong == [], "a package imports from above it: " + "; ".join(wrong)


def test_each_room_imports_only_what_lies_below_it() -> None:
    graph = import_graph(project_modules())
    wrong = []
    for room, allowed in ROOM_IMPORTS.items():
        members = [name for name in graph if name == room or name.startswith(room + ".")]
        assert len(members) > 2, room
        wrong += [f"{name} -> {target}" for name in members for target in sorted(graph[name])
                  if not any(target == a or target.startswith(a + ".") for a in allowed)]
    assert wrong == [], "a room imports from above it: " + "; ".join(wrong)


def _room(module: str, rooms: set[str]) -> str:
    """The room a module lies in: its sub-package, or the module itself beside the rooms."""
    parts = module.split(".")
    return ".".join(parts[:2]) if ".".join(parts[:2]) in rooms else module


def test_every_room_is_declared_and_no_rooms_import_each_other() -> None:
    """Every sub-package of every package is a room of ROOM_IMPORTS, and the graph of rooms (each module
    beside the rooms a node of its own) has no cycle: no two rooms import each other, however indirectly."""
    modules = project_modules()
    subpackages = {name for name, path in modules.items() if path.name == "__init__.py" and name.count(".") == 1}
    assert subpackages == set(ROOM_IMPORTS), "undeclared rooms: " + ", ".join(sorted(subpackages - set(ROOM_IMPORTS)))
    graph = import_graph(modules)
    rooms: dict[str, set[str]] = {}
    for name, targets in graph.items():
        room = _room(name, subpackages)
        rooms.setdefault(room, set()).update(t for t in (_room(t, subpackages) for t in targets) if t != room)
    assert find_cycles(rooms) == [], find_cycles(rooms)


def _room_paths() -> list[tuple[str, str]]:
    from evoscen_sim import moved_paths

    return sorted(moved_paths.ROOM_MODULES.items())


@pytest.mark.parametrize(("old", "new"), _room_paths())
def test_a_path_the_rooms_replaced_is_an_alias_that_warns(old: str, new: str) -> None:
    from evoscen_sim import moved_paths

    assert not (SRC / old.split(".")[0] / (old.replace(".", "/") + ".py")).exists(), old
    target = importlib.import_module(new)
    sys.modules.pop(old, None)
    pattern = (rf"{old.replace('.', '[.]')} is deprecated \(moved in evoscen {moved_paths.ROOMS_MOVED_IN}; "
               rf"removed in {moved_paths.ROOMS_REMOVED_IN}\): use {new.replace('.', '[.]')}$")
    with pytest.warns(DeprecationWarning, match=pattern):
        alias = importlib.import_module(old)
    public = [name for name in vars(target) if not name.startswith("_")]
    assert public, new
    for name in public:
        assert getattr(alias, name) is getattr(target, name), (old, name)
    sys.modules.pop(old, None)


def test_the_new_paths_import_without_a_warning() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for _, new in _room_paths():
            importlib.import_module(new)


MAX_FUNCTION_LINES = 120
MAX_MODULE_LINES = 600
LONG_MODULES_ALLOWED = ("evoscen_sim.road.opendrive",)
"""The OpenDRIVE reader: one element per function, their checks and messages (docs/architecture.md §1)."""


def size_offenders(modules: dict[str, Path]) -> list[str]:
    """Functions and methods (nested ones too) longer than :data:`MAX_FUNCTION_LINES` lines, from ``def``
    (or its first decorator) to the last line, and modules longer than :data:`MAX_MODULE_LINES` lines
    (but :data:`LONG_MODULES_ALLOWED`), each named with its size."""
    import ast

    out = []
    for name, path in sorted(modules.items()):
        text = path.read_text(encoding="utf-8")
        lines = len(text.splitlines())
        if lines > MAX_MODULE_LINES and name not in LONG_MODULES_ALLOWED:
            out.append(f"module {name}: {lines} lines")
        for node in ast.walk(ast.parse(text, filename=str(path))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                first = min([node.lineno, *(d.lineno for d in node.decorator_list)])
                length = node.end_lineno - first + 1
                if length > MAX_FUNCTION_LINES:
                    out.append(f"function {name}.{node.name} (line {node.lineno}): {length} lines")
    return out


def test_the_size_check_finds_long_functions_and_modules(tmp_path) -> None:
    body = "\n".join(f"    x{i} = {i}" for i in range(MAX_FUNCTION_LINES - 1))
    (tmp_path / "ok.py").write_text(f"def fits():\n{body}\n")  # def + 119 lines: 120
    (tmp_path / "long.py").write_text(f"@staticmethod\ndef too_long():\n{body}\n"  # decorator + def + 119: 121
                                      + "\n" * (MAX_MODULE_LINES - MAX_FUNCTION_LINES))
    modules = {"p.ok": tmp_path / "ok.py", "p.long": tmp_path / "long.py"}
    assert size_offenders(modules) == [f"module p.long: {MAX_MODULE_LINES + 1} lines",
                                       "function p.long.too_long (line 2): 121 lines"]


def test_no_function_over_120_lines_and_no_module_over_600() -> None:
    """docs/architecture.md §1: no function over 120 lines, no module over 600 but the OpenDRIVE
    reader, in the packages' sources (their tests aside)."""
    modules = project_modules()
    assert "evoscen_sim.road.opendrive" in modules
    offenders = size_offenders(modules)
    assert offenders == [], "too long: " + "; ".join(offenders)


def test_the_road_facts_are_defined_once() -> None:
    """``MERGE_LANE`` is assigned in the road model alone, and nothing but the road model works out the
    mainline lanes from ``lane_start_s`` (they are ``RoadModel.mainline_lanes``)."""
    import ast

    files = {name: path for name, path in project_modules().items()}
    files.update({f"scripts.{p.stem}": p for p in sorted((SRC.parents[1] / "scripts").glob("*.py"))})
    merge, mainline = [], []
    for name, path in sorted(files.items()):
        text = path.read_text(encoding="utf-8")
        for node in ast.walk(ast.parse(text, filename=str(path))):
            if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "MERGE_LANE" for t in node.targets):
                merge.append(name)
        if "lane_start_s[k] <= 0" in text:
            mainline.append(name)
    assert merge == ["evoscen_sim.road.road_model"]
    assert mainline == [], "mainline lanes worked out outside the road model: " + ", ".join(mainline)
