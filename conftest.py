"""The parts of ``make setup`` beyond the core that the suite tests (docs/development.md, "The suite").

``make test`` installs them all and runs pytest with ``EVOSCEN_TEST_EXTRAS=required``: a part that
is missing then stops the session at its start with one line naming it and what installs it, rather
than letting its tests skip — so the README's test command and CI run the same suite. ``make
test-core`` runs without the variable on the core alone; the tests of the parts not installed skip,
each naming the part.
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import os

import pytest

# part: (Python modules, SUT plug-ins by entry-point name, what installs it)
EXTRAS = {
    "SUMO (scripts/bench.py's reference, the Krauss-vs-SUMO test)": (["libsumo", "sumolib"], [], "requirements-bench.txt"),
    "the FISS/FISS+ example plug-in": (["fiss_planner", "fiss_sut"], ["fiss"], "examples/fiss_sut"),
    "the SUMO SUT example plug-in": (["sumo_sut"], ["sumo_sut"], "examples/sumo_sut"),
    "the export tools and checkers": (["scenariogeneration", "qc_openscenario", "commonroad", "shapely"], [],
                                      "requirements-export.txt"),
}


def missing_extras() -> list[str]:
    """The parts of :data:`EXTRAS` not installed, as ``part (what is missing; what installs it)``."""
    plugins = {ep.name for ep in importlib.metadata.entry_points(group="evoscen.sut")}
    out = []
    for part, (modules, entry_points, source) in EXTRAS.items():
        gone = [m for m in modules if importlib.util.find_spec(m) is None]
        gone += [f"SUT plug-in '{e}'" for e in entry_points if e not in plugins]
        if gone:
            out.append(f"{part} ({', '.join(gone)}; from {source})")
    return out


def pytest_sessionstart(session: pytest.Session) -> None:
    value = os.environ.get("EVOSCEN_TEST_EXTRAS", "")
    if value not in ("", "required"):
        raise pytest.UsageError(f"environment variable EVOSCEN_TEST_EXTRAS = {value!r}: expected 'required' or unset")
    if value == "required" and (missing := missing_extras()):
        raise pytest.UsageError("EVOSCEN_TEST_EXTRAS=required (make test): not installed: " + "; ".join(missing)
                                + " - run make setup (make test-core runs the suite without them)")
