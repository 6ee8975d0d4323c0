"""scripts/traffic_makeup.py: 420-m pieces by hand, bad input."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]


def _module():
    sys.path.insert(0, str(REPO / "scripts"))
    spec = importlib.util.spec_from_file_location("traffic_makeup", REPO / "scripts" / "traffic_makeup.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_pieces_by_hand():
    tm = _module()
    dt = 0.1
    # 50 s at 20 m/s: 1,000 m, two whole 420-m pieces at 20 m/s (the last 160 m dropped)
    s = 20.0 * dt * np.arange(501)
    means, trips = tm.trip_pieces(s, np.full(501, 20.0), dt, np.zeros(501, dtype=bool))
    assert trips == 1 and means == pytest.approx([20.0, 20.0])
    # a new trip at state 300 (after 598 m driven: one piece); then 200 steps, 400 m: none
    new = np.zeros(501, dtype=bool)
    new[300] = True
    means, trips = tm.trip_pieces(s, np.full(501, 20.0), dt, new)
    assert trips == 2 and len(means) == 1


@pytest.mark.parametrize("args, fragment", [
    (["--makeup", "cars", "--seeds", "1", "--steps", "5"], "bvs.makeup"),
    (["--steps", "0"], "--steps"),
])
def test_bad_input_is_one_line(args, fragment):
    res = subprocess.run([sys.executable, "scripts/traffic_makeup.py", *args], cwd=REPO, capture_output=True,
                         text=True, timeout=300, check=False)
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and fragment in lines[0]
