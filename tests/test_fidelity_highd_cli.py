"""scripts/fidelity_highd.py: a bag and the same run made in process measure the same; outputs; bad input.

The script runs in this process (its ``main``), to keep the tests fast; one case runs it as a command."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

REPO = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.e2e


def _module():
    sys.path.insert(0, str(REPO / "scripts"))
    try:
        spec = importlib.util.spec_from_file_location("fidelity_highd_script", REPO / "scripts" / "fidelity_highd.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(REPO / "scripts"))
    return module


MAIN = _module().main


def script(*args: object) -> SimpleNamespace:
    """``main(args)`` with its exit status, stdout and stderr (argparse's exit caught)."""
    import contextlib
    import io

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = MAIN([str(a) for a in args])
        except SystemExit as exc:
            rc = exc.code
    return SimpleNamespace(returncode=rc, stdout=out.getvalue(), stderr=err.getvalue())


def test_a_bag_and_its_run_in_process_give_the_same_table(recorded_run, tmp_path):
    # the shared recorded run: default config (level-0 SUT), seed recorded_run.seed, recorded_run.steps steps
    bag = script(recorded_run.out, "--out", tmp_path / "bag")
    assert bag.returncode == 0, bag.stderr
    here = script("--seeds", 1, "--first-seed", recorded_run.seed, "--steps", recorded_run.steps, "--sut", "level0",
                  "--out", tmp_path / "here")
    assert here.returncode == 0, here.stderr
    a = json.loads((tmp_path / "bag" / "fidelity_highd.json").read_text())
    b = json.loads((tmp_path / "here" / "fidelity_highd.json").read_text())
    assert a["rows"] == b["rows"] and a["lane_changes"] == b["lane_changes"]
    assert a["pieces"] == b["pieces"] and a["settings"]["bags"] == [str(recorded_run.bag_dir)]
    for key in ("per_vehicle_mean_speed_mps", "per_vehicle_min_thw_s", "per_vehicle_min_dhw_m", "per_vehicle_min_ttc_s"):
        assert (tmp_path / "bag" / f"{key}.png").stat().st_size > 0
        h = a["histograms"][key]
        assert sum(h["sim_counts"]) == h["n_in_bins"] <= h["n"]
    assert "| mean speed (m/s) | all |" in bag.stdout and "Krajewski" in bag.stdout


@pytest.mark.parametrize("args, needle", [
    (["no/such/bag"], "no/such/bag: no such bag or run directory"),
    (["--frobnicate"], "unrecognized arguments: --frobnicate"),
    ([], "BAG: expected one or more bags"),
    (["--seeds", "0"], "--seeds = '0': expected an integer >= 1"),
    (["--seeds", "1", "--piece-m", "-3"], "--piece-m '-3': expected a length > 0 (m)"),
    (["--seeds", "1", "--piece-m", "100", "--min-piece-m", "200"], "--min-piece-m '200': expected a length <= --piece-m"),
    (["--reference", "no/such.json"], "no/such.json: cannot read the highD aggregates"),
])
def test_bad_input_is_one_error_line(args, needle):
    res = script(*args)
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and needle in lines[0], res.stderr


def test_a_file_that_is_not_a_bag_is_refused(tmp_path):
    junk = tmp_path / "notes.mcap"
    junk.write_text("not an MCAP file\n")
    res = subprocess.run([sys.executable, "scripts/fidelity_highd.py", str(junk), "--out", str(tmp_path / "out")],
                         cwd=REPO, capture_output=True, text=True, timeout=300, check=False)
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2 and len(lines) == 1 and lines[0].startswith("error: ") and str(junk) in lines[0]
    assert not (tmp_path / "out").exists()
