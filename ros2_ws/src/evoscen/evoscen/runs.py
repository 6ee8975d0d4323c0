"""Run a scenario and score a bag from Python: the face's entry points (docs/plugins.md §19).

:func:`run_scenario` is ``scripts/run_scenario.py`` without the command line: the same checks (the
whole scenario validated before the output directory is touched, a bag replaced only with
``overwrite``), the same runners and output directory (:mod:`evoscen_bringup.runs`), the same bytes.
:func:`score_bag` is ``scripts/evaluate.py``'s scoring: the report a run's evaluator writes, from its
bag alone.

Errors are the project's: :class:`~evoscen_sim.errors.InputError` for bad input (one line naming the
key, file or argument), :class:`~evoscen_sim.errors.PluginFault` for a plug-in that raised,
:class:`~evoscen_sim.errors.HostFault` for the host (a full disk).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from evoscen_sim.errors import InputError

RUNNERS = ("inprocess", "graph")
"""``inprocess``: every core in this process, no middleware; ``graph``: one ROS 2 process per node,
lockstep, on a reserved ROS_DOMAIN_ID (docs/architecture.md §5). Same config and seed, same bag."""


@dataclass
class RunResult:
    """What a run left: its status, its bag, its report."""

    status: int
    """0 for a finished run; otherwise the exit status ``run_scenario.py`` would give (docs/recording.md)."""
    runner: str
    steps: int
    """Steps the run took (the world states in its bag, less the initial one)."""
    wall_time_s: float
    bag_dir: Path | None
    report: dict[str, Any] | None
    """``report.json``'s content; None for a run that was not scored (aborted, or ``evaluate=False``)."""
    report_dir: Path | None = None

    @property
    def score(self) -> float | None:
        """The run's score (``report["intelligence"]["score"]``, docs/evaluation.md), None if unscored."""
        return None if self.report is None else self.report["intelligence"]["score"]


def run_scenario(scenario: str | Path | None = None, overrides: Mapping[str, object] | None = None, *,
                 out: str | Path | None = None, runner: str = "inprocess", overwrite: bool = False,
                 evaluate: bool = True, plots: bool = False, domain_id: int | None = None) -> RunResult:
    """Run a scenario file (None: the shipped default) with ``overrides`` (dotted keys, as on the
    command line: ``{"sut.model": "first_sut", "steps": 300, "seed": 7}``).

    With ``out`` the run writes ``out/bag``, ``out/report`` (with ``evaluate``) and ``out/scenario.yaml``
    like ``run_scenario.py --out``; without it an in-process run records nothing and keeps its report in
    memory (the graph always records: ``out`` is required there).
    """
    from evoscen_sim.config.scenario_config import load_scenario_config

    if runner not in RUNNERS:
        raise InputError(f"runner {runner!r}: expected one of {', '.join(RUNNERS)}")
    cfg = load_scenario_config(scenario, dict(overrides or {}))
    if out is None:
        if runner == "graph":
            raise InputError("runner 'graph': needs out (the graph always records: its evaluator node is part of it)")
        return _inprocess(cfg, None, evaluate=evaluate, plots=plots)
    out = Path(out)
    if runner == "graph":
        return _graph(cfg, out, overwrite=overwrite, evaluate=evaluate, plots=plots, domain_id=domain_id)
    return _inprocess(cfg, out, evaluate=evaluate, plots=plots, overwrite=overwrite)


def _inprocess(cfg: Any, out: Path | None, *, evaluate: bool, plots: bool, overwrite: bool = False) -> RunResult:
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_bringup.runs import write_output
    from evoscen_bringup.scenario import build_scenario

    bag_dir = out / "bag" if out is not None and cfg.recording.enabled else None
    report_dir = out / "report" if out is not None and evaluate else None
    scenario = build_scenario(cfg, partitioned=bag_dir is not None)  # as run_scenario.py builds it
    if out is not None:
        write_output(cfg, out, bag_dir, report_dir, overwrite=overwrite)
    summary = run_inprocess(cfg, bag_dir=bag_dir, scenario=scenario, report_dir=report_dir,
                            evaluate=evaluate, plots=plots)
    return RunResult(status=0, runner="inprocess", steps=summary.steps, wall_time_s=summary.wall_time_s,
                     bag_dir=bag_dir, report=summary.report, report_dir=report_dir)


def _graph(cfg: Any, out: Path, *, overwrite: bool, evaluate: bool, plots: bool, domain_id: int | None) -> RunResult:
    from evoscen_bringup.runs import run_graph_into, steps_of, topic_counts

    if not cfg.recording.enabled:
        raise InputError("runner 'graph' always records (its evaluator node is part of the graph): "
                         "drop recording.enabled: false, or use runner='inprocess'")
    bag_dir = out / "bag"
    report_dir = out / "report" if evaluate else None
    result = run_graph_into(cfg, out, bag_dir, report_dir, domain_id=domain_id, overwrite=overwrite,
                            report_plots=plots)
    steps = steps_of(topic_counts(bag_dir)) if any(bag_dir.glob("*.mcap")) else 0
    report = None
    if report_dir is not None and result.status == 0 and (report_dir / "report.json").is_file():
        report = json.loads((report_dir / "report.json").read_text(encoding="utf-8"))
    return RunResult(status=result.status, runner="graph", steps=steps, wall_time_s=result.wall_time_s,
                     bag_dir=bag_dir, report=report, report_dir=report_dir)


def score_bag(bag: str | Path, *, out: str | Path | None = None, scenario: str | Path | None = None,
              plots: bool = False) -> dict[str, Any]:
    """Score the run in ``bag`` (a bag directory or its .mcap file) under its recorded evaluation
    settings, or those of the scenario file ``scenario``; return the report (``report.json``'s content).
    With ``out`` the report's files are written there too (an empty or new directory)."""
    from evoscen_eval.scoring.report import report_of_stream, write_stream_report
    from evoscen_eval.scoring.rundata import score_bag as score_stream
    from evoscen_sim.config.scenario_config import load_scenario_config

    path = Path(bag)
    if not path.exists():
        raise InputError(f"bag {str(path)!r}: no such bag directory or .mcap file")
    override = load_scenario_config(scenario).evaluation if scenario is not None else None
    run = score_stream(path, override)
    if out is None:
        return report_of_stream(run.stream, run.info, run.warnings)
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise InputError(f"out {str(out)!r}: exists and is not empty; choose another directory")
    return write_stream_report(run.stream, run.info, run.warnings, out, plots=plots, source=str(path),
                               lane_segments=run.lane_segments)
