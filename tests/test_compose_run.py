"""docker/compose-run.sh without containers: a stand-in engine reports each service's exit code and a
stand-in compose tool records how it was called, so the graph's exit status, the line naming a
killed node and the BV containers chosen are checked here (the real graphs run in docker/ci.sh)."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "docker" / "compose-run.sh"

FAKE_ENGINE = """#!/usr/bin/env bash
# ps -a -q --filter label=...project=P --filter label=...service=S: an id when S has a code
case $1 in
  ps) for a in "$@"; do case $a in label=com.docker.compose.service=*) svc=${a#*service=} ;; esac; done
      grep -q "^$svc " "$FAKE_CODES" && echo "id-$svc"; exit 0 ;;
  inspect) id=${@: -1}; grep "^${id#id-} " "$FAKE_CODES" | cut -d' ' -f2 ;;
esac
"""
FAKE_COMPOSE = """#!/usr/bin/env bash
echo "$* ## ${EVOSCEN_IMAGE:-} ## $EVOSCEN_GRAPH_ARGS" >> "$FAKE_CALLS"
"""


def run(tmp_path: Path, codes: dict[str, int], *args: str) -> tuple[int, str, list[str]]:
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir(exist_ok=True)
    for name, text in (("fake-engine", FAKE_ENGINE), ("podman-compose", FAKE_COMPOSE)):
        (bin_dir / name).write_text(text)
        (bin_dir / name).chmod(0o755)
    (tmp_path / "codes").write_text("".join(f"{svc} {code}\n" for svc, code in codes.items()))
    calls = tmp_path / "calls"
    calls.write_text("")
    env = {**os.environ, "PATH": f"{bin_dir}{os.pathsep}{os.environ['PATH']}",
           "EVOSCEN_ENGINE": str(bin_dir / "fake-engine"), "FAKE_CODES": str(tmp_path / "codes"),
           "FAKE_CALLS": str(calls), "EVOSCEN_DOMAIN_LOCK_DIR": str(tmp_path / "locks")}
    for name in ("EVOSCEN_IMAGE", "EVOSCEN_FISS_IMAGE"):
        env.pop(name, None)
    p = subprocess.run(["bash", str(SCRIPT), "--out", str(tmp_path / "out"), *args], env=env,
                       capture_output=True, text=True, timeout=60)
    return p.returncode, p.stderr, calls.read_text().splitlines()


BY_POLICY = {"sim": 0, "eval": 0, "bv-competitive": 0, "bv-mutual": 0, "bv-cooperative": 0, "sut": 0}


def test_default_partition_runs_three_bv_containers(tmp_path: Path) -> None:
    rc, err, calls = run(tmp_path, BY_POLICY, "--", "--steps", "10", "--seed", "3")
    assert rc == 0, err
    up = [c for c in calls if " up " in f" {c} "]
    assert len(up) == 1 and "--profile builtin-sut --profile bv-by-policy" in up[0]
    for svc in ("bv-competitive", "bv-mutual", "bv-cooperative"):
        assert f"node {svc}: exit 0" in err
    assert "error:" not in err


def test_killed_bv_container_is_a_death_named_in_one_line(tmp_path: Path) -> None:
    # bv-mutual killed (SIGKILL: 128 + 9); the simulation then aborted on its deadlines (3)
    rc, err, _ = run(tmp_path, {**BY_POLICY, "sim": 3, "bv-mutual": 137}, "--", "--steps", "10")
    assert rc == 4
    lines = [ln for ln in err.splitlines() if ln.startswith("error:")]
    assert lines == ["error: compose-run: node evoscen_bv_mutual (container bv-mutual) was killed by SIGKILL "
                     "(exit code 137); the run ended early (exit status 4)"]


def test_terminated_container_is_a_death_too(tmp_path: Path) -> None:
    rc, err, _ = run(tmp_path, {**BY_POLICY, "sim": 3, "bv-cooperative": 143}, "--", "--steps", "10")
    assert rc == 4 and "node evoscen_bv_cooperative (container bv-cooperative) was killed by SIGTERM" in err


def test_fault_without_a_death_stays_3_and_bad_input_wins(tmp_path: Path) -> None:
    rc, err, _ = run(tmp_path, {**BY_POLICY, "sim": 3}, "--", "--steps", "10")
    assert rc == 3 and "error:" not in err
    # a node's bad input comes first, even with a killed container beside it
    rc, _, _ = run(tmp_path, {**BY_POLICY, "sim": 3, "bv-competitive": 2, "bv-mutual": 137}, "--", "--steps", "10")
    assert rc == 2


def test_other_partitions_use_one_bv_container(tmp_path: Path) -> None:
    codes = {"sim": 0, "eval": 0, "bv": 0, "sut": 0}
    rc, err, calls = run(tmp_path, codes, "--", "--steps", "10", "--bv-nodes", "single")
    assert rc == 0, err
    assert "--profile bv-one" in next(c for c in calls if " up " in f" {c} ")
    assert "node bv: exit 0" in err and "bv-mutual" not in err
    rc, err, calls = run(tmp_path, codes, "--", "--steps", "10", "--bv-nodes=3")
    assert rc == 0 and "--profile bv-one" in next(c for c in calls if " up " in f" {c} ")
    rc, err, calls = run(tmp_path, BY_POLICY, "--", "--steps", "10", "--bv-nodes", "by_policy")
    assert rc == 0 and "--profile bv-by-policy" in next(c for c in calls if " up " in f" {c} ")
    rc, err, calls = run(tmp_path, codes, "--bv-containers", "one", "--", "--steps", "10")
    assert rc == 0 and "--profile bv-one" in next(c for c in calls if " up " in f" {c} ")
    rc, err, _ = run(tmp_path, {**codes, "bv": 137, "sim": 3}, "--bv-containers", "one", "--", "--steps", "10")
    assert rc == 4 and "error: compose-run: container bv (every BV node of the scenario) was killed by SIGKILL" in err


@pytest.mark.parametrize("value", ["two", ""])
def test_bad_bv_containers_value_is_one_line(tmp_path: Path, value: str) -> None:
    rc, err, calls = run(tmp_path, BY_POLICY, "--bv-containers", value)
    assert rc == 2
    assert err.strip() == f"error: docker/compose-run.sh: --bv-containers '{value}': expected per-node or one"
    assert calls == []


def test_fiss_sut_runs_the_plug_in_in_its_own_container(tmp_path: Path) -> None:
    codes = {**BY_POLICY, "fiss-sut": 0}
    del codes["sut"]
    rc, err, calls = run(tmp_path, codes, "--fiss-sut", "--", "--steps", "300", "--seed", "3")
    assert rc == 0, err
    up = next(c for c in calls if " up " in f" {c} ")
    args, image, graph_args = up.split(" ## ")
    assert "--profile fiss-sut --profile bv-by-policy" in args
    assert image == "localhost/evoscen-fiss:latest"          # every node checks sut.model = fiss
    assert graph_args == "--steps 300 --seed 3 --sut fiss"
    assert "node fiss-sut: exit 0" in err and "node sut:" not in err
    rc, err, _ = run(tmp_path, codes, "--fiss-sut", "--user-sut")
    assert rc == 2 and err.strip() == ("error: docker/compose-run.sh: --user-sut and --fiss-sut: expected at most "
                                       "one of them (one SUT per graph)")
