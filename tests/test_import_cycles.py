"""No import cycles among the project's modules (issue 15).

The graph is built statically with :mod:`ast` from every module of every package
(``ros2_ws/src/<package>/<package>/**/*.py``): an edge for each ``import`` / ``from ... import``
naming another project module, at module level *and* inside functions, classes or ``if`` blocks
(a function-level import that hides a cycle is still a cycle). ``from pkg import name`` counts
as an import of ``pkg.name`` when that is a module, else of ``pkg``. A cycle fails the test,
named module by module; a self-test shows that the detector finds one.
"""

from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SRC = REPO / "ros2_ws" / "src"


def project_modules() -> dict[str, Path]:
    """Dotted module name -> file, for every package under ros2_ws/src."""
    modules: dict[str, Path] = {}
    for pkg_dir in sorted(SRC.iterdir()):
        root = pkg_dir / pkg_dir.name
        if not (root / "__init__.py").is_file():
            continue
        for path in sorted(root.rglob("*.py")):
            parts = list(path.relative_to(pkg_dir).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            modules[".".join(parts)] = path
    return modules


def _resolve(module: str, is_package: bool, level: int, target: str | None) -> str:
    """The absolute name of a (possibly relative) import in ``module``."""
    if level == 0:
        return target or ""
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[: len(base) - (level - 1)]
    return ".".join([*base, target] if target else base)


def import_graph(modules: dict[str, Path]) -> dict[str, set[str]]:
    """Module -> the project modules it imports anywhere in its source."""
    graph: dict[str, set[str]] = {name: set() for name in modules}
    for name, path in modules.items():
        is_package = path.name == "__init__.py"
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        for node in ast.walk(tree):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = _resolve(name, is_package, node.level, node.module)
                targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base
                           for alias in node.names]
            for target in targets:
                # the longest project module the name lies in (``a.b.c`` -> ``a.b`` if ``a.b.c`` is a name)
                parts = target.split(".")
                while parts and ".".join(parts) not in modules:
                    parts.pop()
                if parts and ".".join(parts) != name:
                    graph[name].add(".".join(parts))
    return graph


def find_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (or a self-loop), each as a
    cycle through them: ``[a, b, ..., a]``. Tarjan's algorithm, iterative."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    components: list[list[str]] = []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph.get(root, ()))))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1 or node in graph.get(node, ()):
                    components.append(_cycle_through(sorted(component), graph))
    return components


def _cycle_through(component: list[str], graph: dict[str, set[str]]) -> list[str]:
    """One cycle inside a strongly connected component, from its first module back to it."""
    members = set(component)
    start = component[0]
    # breadth-first search back to start, staying inside the component
    parents: dict[str, str] = {}
    frontier = [start]
    while frontier:
        nxt = []
        for node in frontier:
            for child in sorted(graph.get(node, ())):
                if child not in members:
                    continue
                if child == start:
                    path = [node]
                    while path[-1] != start:
                        path.append(parents[path[-1]])
                    return [start, *reversed(path[:-1]), start] if node != start else [start, start]
                if child not in parents:
                    parents[child] = node
                    nxt.append(child)
        frontier = nxt
    return [*component, component[0]]  # pragma: no cover - a component always has a cycle


def test_detector_finds_a_cycle_in_a_synthetic_graph() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a", "d"}, "d": set(), "e": {"e"}, "f": {"a"}}
    cycles = find_cycles(graph)
    assert sorted(tuple(c) for c in cycles) == [("a", "b", "c", "a"), ("e", "e")]
    assert find_cycles({"a": {"b"}, "b": set()}) == []


def test_detector_sees_function_level_and_relative_imports(tmp_path) -> None:
    pkg = tmp_path / "p"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "x.py").write_text("from . import y\n")
    (pkg / "y.py").write_text("def f():\n    from .x import thing\n    return thing\n")
    modules = {"p": pkg / "__init__.py", "p.x": pkg / "x.py", "p.y": pkg / "y.py"}
    graph = import_graph(modules)
    assert graph["p.x"] == {"p.y"} and graph["p.y"] == {"p.x"}
    assert find_cycles(graph) == [["p.x", "p.y", "p.x"]]


def test_the_project_has_no_import_cycles() -> None:
    modules = project_modules()
    assert "evoscen_sim.config.scenario_config" in modules and "evoscen_sim.model_registry" in modules
    cycles = find_cycles(import_graph(modules))
    assert not cycles, "import cycles: " + "; ".join(" -> ".join(c) for c in cycles)


def test_evoscen_record_depends_only_on_the_contract_and_the_simulation() -> None:
    """The recording package sits below the evaluation and the runners: its modules import only
    evoscen_contract and evoscen_sim among the other packages (evoscen_eval and evoscen_bringup
    import it, never the reverse)."""
    graph = import_graph(project_modules())
    allowed = {"evoscen_record", "evoscen_contract", "evoscen_sim"}
    upward = sorted(f"{name} -> {target}" for name, targets in graph.items() if name.split(".")[0] == "evoscen_record"
                    for target in targets if target.split(".")[0] not in allowed)
    assert "evoscen_record.recorder" in graph
    assert upward == [], "evoscen_record imports from above it: " + "; ".join(upward)
