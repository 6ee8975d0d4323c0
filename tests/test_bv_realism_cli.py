"""scripts/bv_realism.py: --traffic picks traffic.mode, the highD column, bad input."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.e2e


def script(*args: object) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "scripts/bv_realism.py", *map(str, args)], cwd=REPO, capture_output=True,
                          text=True, timeout=300, check=False)


@pytest.mark.parametrize("mode", [None, "loop"])
def test_traffic_option_sets_the_mode(tmp_path, mode):
    out = tmp_path / "f.json"
    extra = [] if mode is None else ["--traffic", mode]
    res = script("--profiles", "driver", "--seeds", 50001, "--steps", 20, "--json", out, *extra)
    assert res.returncode == 0, res.stderr
    want = mode or "window"  # the shipped default
    # the loop carries the uniform make-up only: --traffic loop selects it, the default is highd
    assert f"traffic.mode: {want}; bvs.makeup: {'uniform' if mode == 'loop' else 'highd'}" in res.stdout
    doc = json.loads(out.read_text())
    assert doc["traffic_mode"] == want and doc["args"]["traffic"] == mode
    # the highD column: lane changes per vehicle-km at 120 km/h (per-vehicle counts, shipped aggregates);
    # THW: highD's aggregate is a per-vehicle minimum, not comparable with per-state samples, so none printed
    line = next(x for x in res.stdout.splitlines() if x.startswith("BV lane changes / veh-km"))
    assert line.split()[-1] == "0.295"
    assert next(x for x in res.stdout.splitlines() if x.startswith("THW median")).split()[-1] == "-"
    assert doc["highd"] == {"bv_lane_changes_per_vehicle_km": pytest.approx(0.295)}
    assert "Krajewski" in res.stdout


def test_bad_traffic_mode_is_refused():
    res = script("--traffic", "ring")
    assert res.returncode == 2 and "invalid choice" in res.stderr
