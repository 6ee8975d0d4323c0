#!/usr/bin/env python3
"""Run the same tests several times in a row and count, per test, how many runs it passed.

    python scripts/repeat_tests.py --times 30 -- tests/test_graph.py -k killed_controller_aborts_cleanly
    make test-repeat REPEAT=30 REPEAT_TESTS='tests/test_graph.py -k killed_controller_aborts_cleanly'

For the timing-sensitive tests (node graphs whose controllers are killed, stopped or interrupted): a
race shows in some runs only, so one green run says little (docs/development.md, "Repeating
timing-sensitive tests"). Each run is a fresh ``python -m pytest`` process (fresh module-scoped
fixtures: a fresh graph), with a JUnit XML report read back for the per-test outcomes. Prints one
line per run and a table: test, passed, failed, skipped (of N); the failures' first lines are kept
under ``--out`` (default ``runs/repeat_tests/``). Exit status 0 when every test passed in every
run, 1 when any failed, 2 for bad arguments.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from collections import defaultdict
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli

REPO = Path(__file__).resolve().parents[1]


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = cli.parser("repeat_tests.py", __doc__)
    p.usage = "%(prog)s [--times N] [--out DIR] [--stop-on-failure] -- PYTEST_ARGS ..."
    p.add_argument("--times", default="10", help="how many runs (default 10)")
    p.add_argument("--out", type=Path, default=REPO / "runs" / "repeat_tests",
                   help="where each run's JUnit report and failures go (default runs/repeat_tests/)")
    p.add_argument("--stop-on-failure", action="store_true", help="stop after the first run with a failure")
    p.add_argument("pytest_args", nargs=argparse.REMAINDER, help="after --: what pytest runs (paths, -k, -m)")
    args = p.parse_args(argv)
    rest = args.pytest_args[1:] if args.pytest_args[:1] == ["--"] else args.pytest_args
    if not rest:
        p.error("expected the tests to repeat after --, e.g. -- tests/test_graph.py -k killed")
    args.pytest_args = rest
    args.times = cli.positive_int("--times", args.times)
    return args


def outcomes(junit: Path) -> dict[str, tuple[str, str]]:
    """``{test id: (outcome, first line of the failure)}`` of one JUnit XML report (outcome: passed,
    failed, error or skipped)."""
    got: dict[str, tuple[str, str]] = {}
    for case in ET.parse(junit).getroot().iter("testcase"):
        name = f"{case.get('classname', '')}::{case.get('name', '')}"
        outcome, text = "passed", ""
        for tag in ("failure", "error", "skipped"):
            el = case.find(tag)
            if el is not None:
                outcome = "failed" if tag == "failure" else tag
                text = (el.get("message") or el.text or "").strip().splitlines()[:1]
                text = text[0][:300] if text else ""
                break
        if got.get(name, ("passed",))[0] == "passed":  # a setup error and a test failure: the failure counts
            got[name] = (outcome, text)
    return got


def main(argv: list[str] | None = None) -> int:
    return cli.run(lambda: repeat(parse_args(argv)))


def repeat(args: argparse.Namespace) -> int:
    """Run pytest ``args.times`` times and print the table; 0 all passed, 1 any failed, 2 pytest ran nothing."""
    args.out.mkdir(parents=True, exist_ok=True)
    counts: dict[str, dict[str, int]] = defaultdict(lambda: defaultdict(int))
    failures: list[str] = []
    runs = 0
    for k in range(1, args.times + 1):
        junit = args.out / f"run{k}.xml"
        junit.unlink(missing_ok=True)
        t0 = time.monotonic()
        proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", f"--junitxml={junit}",
                               *args.pytest_args], cwd=REPO, capture_output=True, text=True, check=False)
        runs += 1
        if not junit.exists():  # pytest stopped before running anything: a usage or collection error
            tail = (proc.stdout + proc.stderr).strip().splitlines()[-3:]
            print(f"error: repeat_tests: pytest ran no test (exit status {proc.returncode}): {' | '.join(tail)}",
                  file=sys.stderr)
            return 2
        result = outcomes(junit)
        bad = {name: text for name, (o, text) in result.items() if o in ("failed", "error")}
        for name, (o, _) in result.items():
            counts[name][o] += 1
        print(f"run {k}/{args.times}: {len(result) - len(bad)} of {len(result)} passed or skipped, "
              f"{len(bad)} failed ({time.monotonic() - t0:.0f} s)", flush=True)
        for name, text in bad.items():
            failures.append(f"run {k}: {name}: {text}")
            (args.out / f"run{k}.log").write_text(proc.stdout + proc.stderr, encoding="utf-8")
        if bad and args.stop_on_failure:
            break
    width = max(len(n) for n in counts) if counts else 4
    print(f"\n{'test':<{width}}  passed  failed  skipped  (of {runs} runs)")
    for name in sorted(counts):
        c = counts[name]
        print(f"{name:<{width}}  {c['passed']:>6}  {c['failed'] + c['error']:>6}  {c['skipped']:>7}")
    for line in failures:
        print(line)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
