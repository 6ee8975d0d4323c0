"""Fuzzed inputs for the fault campaign (:mod:`evoscen_experiments.faults`): the shipped scenario YAML,
OpenDRIVE map, a bag, HighD recordings and CLI values, mutated by a seeded generator, each loaded in
this process with a 20 s alarm; what each ended with (loaded, a one-line error, a traceback, a hang).
The command lines fuzzed are the scripts' ``main(argv)`` (:data:`CLIS`), handed in by the caller."""

from __future__ import annotations

import contextlib
import io
import os
import re
import shutil
import signal
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

CLIS = ("run_scenario", "evaluate", "replay", "export_highd")
"""The scripts whose ``main(argv)`` :func:`fuzz` calls with hostile values, in the order it draws them."""


class _Alarm(Exception):
    pass


def _on_alarm(signum, frame):
    raise _Alarm


def _mutate_text(text: str, rng: np.random.Generator) -> str:
    """One hostile edit of a text file."""
    lines = text.split("\n")
    op = int(rng.integers(0, 9))
    if op == 0:  # flip bytes
        b = bytearray(text.encode("utf-8"))
        for _ in range(int(rng.integers(1, 8))):
            b[int(rng.integers(0, len(b)))] = int(rng.integers(0, 256))
        return b.decode("utf-8", errors="surrogateescape")
    if op == 1:  # cut short
        return text[: int(rng.integers(0, len(text)))]
    if op == 2:  # drop a line
        del lines[int(rng.integers(0, len(lines)))]
        return "\n".join(lines)
    if op == 3:  # a value replaced by a hostile token
        tokens = ["1e308", "-1", "0", "nan", "inf", "''", "[]", "{}", "0x10", "9" * 40, "!!python/object:os.system x",
                  "&a [*a, *a]", "~", "true", "\u0000", "-0.0", "1e-12"]
        i = int(rng.integers(0, len(lines)))
        if ":" in lines[i]:
            key, _, _ = lines[i].partition(":")
            lines[i] = f"{key}: {tokens[int(rng.integers(0, len(tokens)))]}"
        return "\n".join(lines)
    if op == 4:  # deep nesting
        depth = int(rng.integers(50, 5000))
        return "[" * depth + "]" * depth
    if op == 5:  # NUL bytes
        i = int(rng.integers(0, len(text)))
        return text[:i] + "\x00" + text[i:]
    if op == 6:  # duplicate a line
        i = int(rng.integers(0, len(lines)))
        lines.insert(i, lines[i])
        return "\n".join(lines)
    if op == 7:  # numbers scaled wildly
        return re.sub(r"(?<![\w.])(\d+(\.\d+)?)", lambda m: str(float(m.group(1)) * float(rng.choice([-1, 1e9, 1e-9, 0]))),
                      text, count=int(rng.integers(1, 5)))
    return text.replace(" ", "\t", int(rng.integers(1, 20)))  # tabs


def _finite_at_least(text: str, low: float) -> bool:
    """Whether ``text`` reads as a finite number >= ``low`` (Python's own float parsing)."""
    try:
        value = float(text)
    except ValueError:
        return False
    return np.isfinite(value) and value >= low


def _one_line_error(exc: BaseException) -> bool:
    return "\n" not in str(exc).strip() and bool(str(exc).strip())


def fuzz(n: int, rng: np.random.Generator, work: Path, clis: Mapping[str, Callable[[list[str]], int]]) -> list[dict]:
    """``n`` fuzzed inputs over the five input kinds; one dict per input. ``clis``: the ``main(argv)`` of
    each script of :data:`CLIS`, by name."""
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_bringup.scenario import build_scenario
    from evoscen_eval.naturalistic.highd import load_recording
    from evoscen_sim.config.scenario_config import load_scenario_config, share_path
    from evoscen_sim.errors import InputError
    from evoscen_sim.road.road_model import DEFAULT_MAP_PATH, load_road

    default_yaml = share_path("config/default_scenario.yaml")
    yaml_text = default_yaml.read_text(encoding="utf-8")
    map_text = Path(DEFAULT_MAP_PATH).read_text(encoding="utf-8")
    base_bag = work / "fuzz-base" / "bag"
    run_inprocess(load_scenario_config(None, {"steps": 60, "seed": 1}), bag_dir=base_bag, evaluate=False)
    highd_dir = work / "fuzz-base" / "highd"
    run_cli, evaluate_cli, replay_cli, export_cli = (clis[name] for name in CLIS)
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        export_cli([str(base_bag), str(highd_dir), "--recording-id", "1"])
    highd_files = sorted(highd_dir.glob("*.csv"))
    hostile = ["0x10", "1e300", "-1", "nan", "", " ", "１２", "1_000", "9" * 30, "--", "-0", "inf", "\x00", "3.5"]
    kinds = ("config", "map", "bag", "highd", "cli")
    results = []
    old = signal.signal(signal.SIGALRM, _on_alarm)
    cwd = os.getcwd()
    os.chdir(work)  # a CLI value that names the current directory writes here, not into the checkout
    try:
        for i in range(n):
            kind = kinds[i % len(kinds)]
            case = work / f"fuzz-{i}"
            case.mkdir(parents=True, exist_ok=True)
            outcome, detail = "ok", ""
            signal.alarm(20)
            sink_out, sink_err = io.StringIO(), io.StringIO()
            try:
                with contextlib.redirect_stdout(sink_out), contextlib.redirect_stderr(sink_err):
                    if kind == "config":
                        p = case / "scenario.yaml"
                        p.write_text(_mutate_text(yaml_text, rng), encoding="utf-8", errors="surrogateescape")
                        build_scenario(load_scenario_config(p, {"steps": 5}))
                    elif kind == "map":
                        p = case / "map.xodr"
                        p.write_text(_mutate_text(map_text, rng), encoding="utf-8", errors="surrogateescape")
                        load_road(p)
                    elif kind == "bag":
                        bag = case / "bag"
                        shutil.copytree(base_bag, bag)
                        target = rng.choice(sorted(bag.iterdir()))
                        data = bytearray(target.read_bytes())
                        if rng.random() < 0.5:
                            data = data[: int(rng.integers(0, len(data)))]
                        else:
                            for _ in range(int(rng.integers(1, 16))):
                                data[int(rng.integers(0, len(data)))] = int(rng.integers(0, 256))
                        target.write_bytes(bytes(data))
                        code = evaluate_cli([str(bag), "--out", str(case / "report"), "--no-plots"])
                        if code not in (0, 2):
                            outcome, detail = "bad-exit", f"evaluate.py exit {code}"
                    elif kind == "highd":
                        rec = case / "highd"
                        shutil.copytree(highd_dir, rec)
                        target = highd_files[int(rng.integers(0, len(highd_files)))].name
                        text = (rec / target).read_text(encoding="utf-8")
                        (rec / target).write_text(_mutate_text(text, rng), encoding="utf-8", errors="surrogateescape")
                        load_recording(rec, 1)
                    else:
                        tool = int(rng.integers(0, 4))
                        tok = hostile[int(rng.integers(0, len(hostile)))]
                        detail = f"tool {CLIS[tool]} value {tok!r}"
                        if tool == 0:
                            flag = str(rng.choice(["--steps", "--seed", "--bvs", "--mix", "--sut", "--out"]))
                            argv = ["--mode", "inprocess", "--no-record", "--quiet", "--steps", "3",
                                    "--out", str(case / "o"), flag, tok]
                            code = run_cli(argv)
                        elif tool == 1:
                            code = evaluate_cli([str(base_bag), "--out", tok or str(case / "r"), "--no-plots"])
                        elif tool == 2:
                            flag = str(rng.choice(["--rate", "--start-delay", "--wait-timeout", "--wait-subscribers"]))
                            if flag in ("--start-delay", "--wait-timeout") and _finite_at_least(tok, 10.0):
                                flag = "--rate"  # a long delay or wait that is asked for is no hang
                            code = replay_cli([str(base_bag), flag, tok, "--rate", "0", "--wait-timeout", "0.1"])
                        else:
                            flag = str(rng.choice(["--frame-rate", "--recording-id"]))
                            code = export_cli([str(base_bag), str(case / "h"), flag, tok])
                        if code not in (0, 1, 2):
                            outcome, detail = "bad-exit", f"exit {code}"
            except InputError as exc:
                outcome = "error" if _one_line_error(exc) else "multi-line-error"
                detail = str(exc)[:160]
            except SystemExit as exc:  # argparse: usage + one error line, exit 2
                outcome = "error" if exc.code == 2 else "bad-exit"
                detail = f"SystemExit {exc.code}"
            except _Alarm:
                outcome, detail = "hang", f"no end within 20 s {detail}"
            except BaseException as exc:  # noqa: BLE001 - a traceback: what the campaign looks for
                outcome, detail = "traceback", f"{type(exc).__name__}: {str(exc)[:160]}"
            finally:
                signal.alarm(0)
            if "Traceback" in sink_err.getvalue():
                outcome, detail = "traceback", sink_err.getvalue().strip().splitlines()[-1][:160]
            if outcome in ("ok", "error") and kind == "cli":
                detail = ""
            results.append({"case": i, "kind": kind, "outcome": outcome, "detail": detail})
            shutil.rmtree(case, ignore_errors=True)
    finally:
        signal.signal(signal.SIGALRM, old)
        os.chdir(cwd)
    return results
