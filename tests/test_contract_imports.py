"""The cores are ROS-free, and the contract's facts have one definition (issue 15).

* Importing a core module (the world, the scores, the drivers, the in-process runner, the pure
  half of the contract) loads no ROS: no ``rclpy``, no ``rosidl*``, no message package
  (``*_msgs``, ``builtin_interfaces``). Checked in a fresh interpreter, module by module, and
  the check is shown to catch the ROS binding (``evoscen_contract.topics``).
* Exit statuses, role and policy codes, event and topic names are written once, in
  ``evoscen_contract.contract``: a scan of the package sources and the scripts finds no other
  literal definition, and the modules that used to keep copies hold the contract's objects.
  The share-directory look-up (``get_package_share_directory``) is written once too.
"""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

#: Core modules, in import order: each must leave no ROS module in ``sys.modules``.
CORE_MODULES = (
    "evoscen_contract.contract",
    "evoscen_contract.qos",
    "evoscen_contract.cdr",
    "evoscen_contract.cdr_markers",
    "evoscen_contract.wire",
    "evoscen_sim.config.scenario_config",
    "evoscen_sim.physics.world",
    "evoscen_sim.danger.safety",
    "evoscen_sim.danger.events",
    "evoscen_sim.road.road_model",
    "evoscen_sim.loop.view",
    "evoscen_sim.traffic.spawn",
    "evoscen_sim.model_registry",
    "evoscen_sim.scenario_builders",
    "evoscen_sim.loop.step_loop",
    "evoscen_sim.road",
    "evoscen_sim.config",
    "evoscen_sim.physics",
    "evoscen_sim.danger",
    "evoscen_sim.traffic",
    "evoscen_sim.loop",
    "evoscen_sim.road.opendrive",
    "evoscen_sim.road.road_kernels",
    "evoscen_sim.config.config_checks",
    "evoscen_sim.config.config_load",
    "evoscen_sim.config.config_schema",
    "evoscen_sim.limits",
    "evoscen_sim.physics.collision",
    "evoscen_sim.physics.control",
    "evoscen_sim.loop.hand_built",
    "evoscen_sim.physics.idm",
    "evoscen_sim.physics.neighbors",
    "evoscen_sim.traffic.scenario_params",
    "evoscen_sim.physics.window",
    "evoscen_sim.traffic.makeup",
    "evoscen_sim.errors",
    "evoscen_sim.jit",
    "evoscen_sim.physics.vehicle",
    "evoscen_bv.level0",
    "evoscen_bv.learned",
    "evoscen_bv.bv_models",
    "evoscen_sut.krauss",
    "evoscen_sut.mobil",
    "evoscen_sut.nilsson",
    "evoscen_sut.stackelberg",
    "evoscen_sut.mutant",
    "evoscen_sut.sut_models",
    "evoscen_record.schemas",
    "evoscen_record.canonical_cdr",
    "evoscen_record.bag_file",
    "evoscen_record.metadata_yaml",
    "evoscen_record.mcap_internals",
    "evoscen_record.bag_reader",
    "evoscen_record.scenario_record",
    "evoscen_record.step_recorder",
    "evoscen_record.bag_writer",
    "evoscen_eval.scoring.rundata",
    "evoscen_eval.scoring.metrics",
    "evoscen_eval.scoring.report",
    "evoscen_eval.naturalistic.bv_realism",
    "evoscen_bringup.scenario",
    "evoscen_bringup.inprocess",
)

_PROBE = r"""
import importlib, json, sys

def ros(names):
    out = set()
    for name in names:
        top = name.split(".")[0]
        if top in ("rclpy", "rosgraph_msgs", "builtin_interfaces") or top.startswith("rosidl") or top.endswith("_msgs"):
            out.add(name)
    return out

seen = ros(sys.modules)
result = {"before": sorted(seen), "modules": {}}
for name in sys.argv[1:]:
    importlib.import_module(name)
    now = ros(sys.modules)
    result["modules"][name] = sorted(now - seen)
    seen = now
print(json.dumps(result))
"""


def _probe(modules: list[str]) -> dict:
    """Import ``modules`` in order in a fresh interpreter; the ROS modules each one added."""
    proc = subprocess.run([sys.executable, "-c", _PROBE, *modules], cwd=REPO, env=dict(os.environ),
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_core_modules_import_no_ros() -> None:
    result = _probe([*CORE_MODULES, "evoscen_contract.topics"])
    assert result["before"] == []
    offenders = {name: mods for name, mods in result["modules"].items() if name in CORE_MODULES and mods}
    assert offenders == {}, f"core modules that load ROS: {offenders}"
    # the probe sees ROS when it is there: the binding loads rclpy's message packages
    binding = set(result["modules"]["evoscen_contract.topics"])
    assert {"rosgraph_msgs", "sensor_msgs", "diagnostic_msgs", "builtin_interfaces"} <= binding


# --------------------------------------------------------------------------- one definition


def _contract():
    from evoscen_contract import contract

    return contract


_FACT_NAME_PREFIXES = ("EXIT_", "ROLE_", "POLICY_", "DOCUMENTED_", "NODE_EXIT", "GRAPH_EXIT")


def _targets(node: ast.AST) -> list[str]:
    targets = node.targets if isinstance(node, ast.Assign) else [node.target]
    names: list[str] = []
    for t in targets:
        names += [n.id for n in ast.walk(t) if isinstance(n, ast.Name)]
    return names


def duplicate_facts(source: str, where: str) -> list[str]:
    """Literal definitions of contract facts in ``source``.

    Flags: an assignment to a code-like name (``EXIT_*``, ``ROLE_*``, ``POLICY_*``, ...) whose
    value holds an int literal; a dict literal mapping policy names to their codes; a string
    literal equal to an event name or a topic name (docstrings aside).
    """
    c = _contract()
    names = set(c.EVENT_NAMES) | set(c.TOPIC_TYPES)
    tree = ast.parse(source)
    docstrings = {id(n.value) for n in ast.walk(tree) if isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant)}
    found: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.Assign, ast.AnnAssign)) and node.value is not None:
            facts = [n for n in _targets(node) if n.startswith(_FACT_NAME_PREFIXES)]
            literal = any(isinstance(v, ast.Constant) and type(v.value) is int for v in ast.walk(node.value))
            if facts and literal:
                found.append(f"{where}:{node.lineno}: {', '.join(facts)} defined with literals")
        elif isinstance(node, ast.Dict):
            pairs = [(k.value, v.value) for k, v in zip(node.keys, node.values)
                     if isinstance(k, ast.Constant) and isinstance(v, ast.Constant)]
            if len(pairs) >= 2 and all(c.POLICY_CODES.get(k) == v and type(v) is int for k, v in pairs):
                found.append(f"{where}:{node.lineno}: policy codes as a dict literal")
        elif (isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in names
              and id(node) not in docstrings):
            found.append(f"{where}:{node.lineno}: {node.value!r} spelled as a literal")
    return found


def _sources() -> list[Path]:
    """The package sources (not their tests) and the scripts; not the contract module itself.

    ``examples/`` is left out on purpose: the external SUT node there is a user's node written
    against the published contract, without importing evoscen.
    """
    files = sorted(REPO.glob("ros2_ws/src/*/evoscen_*/**/*.py")) + sorted(REPO.glob("scripts/*.py"))
    own = REPO / "ros2_ws/src/evoscen_contract/evoscen_contract/contract.py"
    return [f for f in files if f != own]


def test_the_scan_finds_copies() -> None:
    """The scanner flags each kind of copy (so the tree-wide scan below can fail)."""
    copies = (
        "EXIT_OK, EXIT_BAD_INPUT = 0, 2\n"
        "ROLE_SUT = 1\n"
        "DOCUMENTED_EXIT = (0, 2, 3, 4, 130)\n"
        'CODES = {"mutual": 1, "competitive": 2}\n'
        'def f(e):\n    return e["name"] == "evoscen/run_end" or e == "/evoscen/world"\n'
    )
    assert len(duplicate_facts(copies, "x.py")) == 6
    derived = (
        '"""Docstring naming "/evoscen/world"."""\n'
        "from evoscen_contract.contract import EXIT_OK, POLICY_CODES\n"
        'POLICY_CODE = {name: POLICY_CODES[name] for name in ("mutual",)}\n'
        "STATUS = EXIT_OK\n"
    )
    assert duplicate_facts(derived, "y.py") == []


def test_facts_are_defined_once() -> None:
    sources = _sources()
    assert len(sources) > 50
    found = []
    for path in sources:
        found += duplicate_facts(path.read_text(encoding="utf-8"), str(path.relative_to(REPO)))
    assert found == [], "\n".join(found)


def test_share_lookup_is_defined_once() -> None:
    users = [str(p.relative_to(REPO)) for p in _sources() if "get_package_share_directory" in p.read_text(encoding="utf-8")]
    assert users == ["ros2_ws/src/evoscen_sim/evoscen_sim/share.py"]


def test_former_copies_are_the_contract_objects() -> None:
    from evoscen_bringup import graph_runner
    from evoscen_contract import topics as T
    from evoscen_eval.naturalistic import bv_realism
    from evoscen_sim import scenario_builders as scenario
    from evoscen_sim.physics import world

    c = _contract()
    assert scenario.POLICY_CODES is c.POLICY_CODES
    assert T.POLICY_CODES is c.POLICY_CODES and T.WORLD_FIELDS is c.WORLD_FIELDS and T.EVENT_KEY_TYPES is c.EVENT_KEY_TYPES
    assert (world.ROLE_BV, world.ROLE_SUT, bv_realism.ROLE_BV) == (c.ROLE_BV, c.ROLE_SUT, c.ROLE_BV)
    assert bv_realism.POLICY_NAMES == {code: name for code, name in c.POLICY_NAMES.items() if name in c.SOCIAL_POLICIES}
    assert graph_runner.NODE_EXIT_STATUSES is c.NODE_EXIT_STATUSES
    assert [spec.name for spec in T.CONTRACT] == list(c.TOPIC_TYPES)
    assert all(spec.type_name == c.TOPIC_TYPES[spec.name] for spec in T.CONTRACT)


@pytest.mark.parametrize("script", ["run_scenario.py", "evaluate.py", "graph_node.py", "fault_campaign.py"])
def test_scripts_use_the_contract_exit_statuses(script: str) -> None:
    """A script's statuses are the contract's: imported from it, or those of ``evoscen.cli.run``, the
    doors' one ending (which imports them from the contract)."""
    tree = ast.parse((REPO / "scripts" / script).read_text(encoding="utf-8"))
    imported = {a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module == "evoscen_contract.contract"
                for a in n.names}
    through_cli = any(isinstance(n, ast.Attribute) and n.attr == "run" and isinstance(n.value, ast.Name)
                      and n.value.id == "cli" for n in ast.walk(tree))
    assert {"EXIT_BAD_INPUT"} <= imported or through_cli
