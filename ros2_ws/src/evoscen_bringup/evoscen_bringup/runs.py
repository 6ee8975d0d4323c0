"""A scenario run into an output directory: what ``scripts/run_scenario.py``, ``scripts/graph_node.py``
and :func:`evoscen.run_scenario` share.

* :data:`SCENARIO_OPTIONS` and :func:`scenario_overrides`: the scenario options of the command line and
  the configuration keys they override;
* :func:`write_output`: the output directory prepared (:func:`~evoscen_bringup.output.prepare_output`)
  and ``scenario.yaml`` written, a write that fails a :class:`~evoscen_sim.errors.HostFault`;
* :func:`run_graph_into`: the node graph on a ROS_DOMAIN_ID reserved for it, reserved before the output
  directory is touched (docs/architecture.md §5); :func:`topic_counts` and :func:`steps_of`: what its bag holds;
* :func:`run_command`: ``run_scenario.py``'s run with its checks (everything validated before the
  output directory is touched, so a bad input never costs an existing bag) and the lines it prints,
  the outcome of each ending (docs/recording.md, "Endings and exit statuses").

Bad input is a one-line :class:`~evoscen_sim.errors.InputError`, a fault of the host a
:class:`~evoscen_sim.errors.HostFault`: the caller says them (``evoscen.cli.run``).
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from evoscen_contract.contract import (EXIT_BAD_INPUT, EXIT_FAULT, EXIT_HOST_FAULT, EXIT_INTERRUPTED, EXIT_NODE_DIED,
                                       EXIT_OK, TOPIC_WORLD)
from evoscen_sim.errors import HostFault, InputError, PluginFault

from evoscen_bringup.node_logs import LOG_DIR

MODES = ("graph", "inprocess")
"""``run_scenario.py --mode``: one ROS 2 process per node (lockstep), or every core in one process."""
ABORTED = (EXIT_BAD_INPUT, EXIT_FAULT, EXIT_NODE_DIED)
"""Statuses of a graph run that ended early (a refused answer, a controller fault, a dead node): no score."""

SCENARIO_OPTIONS: tuple[tuple[str, str, str], ...] = (
    ("--steps", "steps", "number of steps (overrides 'steps')"),
    ("--seed", "seed", "random seed (overrides 'seed')"),
    ("--sut", "sut.model", "SUT model name (overrides 'sut.model')"),
    ("--bvs", "bvs.count", "number of background vehicles (overrides 'bvs.count')"),
    ("--mix", "bvs.mix", "policy mix competitive:mutual:cooperative, e.g. 4:3:3 (overrides 'bvs.mix')"),
    ("--bv-nodes", "bvs.nodes", "BV nodes: by_policy, single or a number N (overrides 'bvs.nodes'; "
                                "docs/architecture.md §5, \"BV nodes\")"),
)
"""The scenario options of ``run_scenario.py`` and ``graph_node.py``: option, the key it overrides, its help."""


def option_dest(option: str) -> str:
    """The attribute an option's value is kept under (``--bv-nodes``: ``bv_nodes``), as argparse names it."""
    return option.lstrip("-").replace("-", "_")


def scenario_overrides(values: Mapping[str, Any]) -> dict[str, str]:
    """The configuration keys the scenario options override, only those given (``values`` by
    :func:`option_dest`, e.g. ``vars(args)``)."""
    return {key: values[option_dest(option)] for option, key, _help in SCENARIO_OPTIONS
            if values.get(option_dest(option)) is not None}


def write_output(cfg, out: Path, bag_dir: Path | None, report_dir: Path | None, *, overwrite: bool) -> None:
    """Prepare ``out`` (its bag and report folders free; replaced only with ``overwrite``) and write the
    resolved configuration to ``out/scenario.yaml``."""
    from evoscen_bringup.output import prepare_output
    from evoscen_sim.config.scenario_config import dump_config

    prepare_output(out, bag_dir, report_dir, overwrite=overwrite)
    try:
        dump_config(cfg, out / "scenario.yaml")
    except OSError as exc:
        raise HostFault.of(exc, out / "scenario.yaml") from None


def run_graph_into(cfg, out: Path, bag_dir: Path, report_dir: Path | None, *, domain_id: int | None = None,
                   overwrite: bool = False, announce: Callable[[Any], None] | None = None, **options):
    """Run the node graph of ``cfg`` into ``out`` (``GraphOptions(**options)``) on ``domain_id`` or a free
    domain, reserved before the output directory is touched and held until the graph has ended;
    ``announce(opts)`` is told the graph's options before it starts. Returns the
    :class:`~evoscen_bringup.graph_runner.GraphResult`."""
    from evoscen_bringup.domains import reserve_domain
    from evoscen_bringup.graph_runner import GraphOptions, run_graph
    from evoscen_bringup.output import prepare_output
    from evoscen_sim.config.scenario_config import dump_config

    with reserve_domain(domain_id) as domain:
        prepare_output(out, bag_dir, report_dir, overwrite=overwrite)
        try:
            dump_config(cfg, out / "scenario.yaml")
            opts = GraphOptions(domain_id=domain, report_dir=report_dir, **options)
            if announce is not None:
                announce(opts)
            return run_graph(cfg, out, bag_dir, opts)
        except OSError as exc:  # scenario.yaml, the parameter files: before step 0
            raise HostFault.of(exc, exc.filename or out) from None


def topic_counts(bag_dir: Path) -> dict[str, int]:
    """Messages per topic of the bag in ``bag_dir`` (InputError if it cannot be read)."""
    from evoscen_record.bag_reader import open_bag_reader

    counts: dict[str, int] = {}
    for topic, _type, _t, _data in open_bag_reader(bag_dir):
        counts[topic] = counts.get(topic, 0) + 1
    return counts


def steps_of(counts: Mapping[str, int]) -> int:
    """The steps a run took: its world states (:func:`topic_counts`) less the initial one."""
    return max(counts.get(TOPIC_WORLD, 1) - 1, 0)


def print_scores(report_dir: Path) -> None:
    """The scores from ``report_dir/report.json``, D first (:func:`~evoscen_eval.scoring.report_text.score_lines`,
    docs/evaluation.md §10), the report's warnings on stderr, and where the report is."""
    from evoscen_eval.scoring.report_text import score_lines

    path = report_dir / "report.json"
    if not path.is_file():
        print(f"error: no report was written ({path} is missing)", file=sys.stderr)
        return
    r = json.loads(path.read_text(encoding="utf-8"))
    for line in score_lines(r):
        print(line)
    for warning in r["warnings"]:
        print(f"warning: {warning}", file=sys.stderr)
    print(f"report: {report_dir / 'report.md'}")


def graph_outcome(result, cfg, out: Path, bag_dir: Path, report_dir: Path) -> int:
    """Print what a graph run left (its steps, nodes and bag; its scores, unless it ended early) and
    return its exit status."""
    if result.status == EXIT_HOST_FAULT:  # the recorder said in one line what became of the bag
        return result.status
    if not any(bag_dir.glob("*.mcap")) if bag_dir.is_dir() else True:
        # an error line only when no node said one (a failed run has said why in its own line)
        print(f"{'error: ' if result.status == EXIT_OK else ''}no bag was written in {bag_dir} "
              "(the run ended during start-up)", file=sys.stderr)
        return result.status or EXIT_FAULT
    try:
        counts = topic_counts(bag_dir)
    except InputError as exc:  # an error line only when the run has not said one (the recorder's death)
        print(f"{'error: ' if result.error is None else ''}the bag is not readable ({exc}); if the recorder was "
              f"killed, recover what it wrote with: python scripts/reindex.py {bag_dir}", file=sys.stderr)
        return result.status or EXIT_FAULT
    steps = steps_of(counts)
    print(f"steps: {steps}  domain: {result.domain_id}  wall: {result.wall_time_s:.2f} s (the graph's start-up to "
          f"shut-down; its stepping: the lockstep line)  "
          f"nodes: " + ", ".join(f"{n}={s}" for n, s in result.node_status.items()))
    try:
        size = sum(f.stat().st_size for f in bag_dir.iterdir())
    except OSError as exc:
        raise HostFault.of(exc, exc.filename or out) from None
    print(f"bag: {bag_dir}  ({sum(counts.values())} messages, {size / 1e6:.2f} MB)")
    if result.status in ABORTED:  # a controller fault or a dead node ended the run early: not scored
        print(f"aborted: the run ended at step {steps} of {cfg.steps} (exit status {result.status}); "
              "the run is not scored")
        return result.status
    if result.status == EXIT_INTERRUPTED:  # the in-process runner's line; scored if the recorder saw run_end
        print(f"interrupted: the bag {bag_dir} is finished", file=sys.stderr)
        if not (report_dir / "report.json").is_file():
            return result.status
    print_scores(report_dir)
    return result.status


def _graph_command(cfg, out: Path, bag_dir: Path, report_dir: Path, *, domain_id: int | None, overwrite: bool,
                   external_sut: bool, **options) -> int:
    """``--mode graph``: the graph run, announced on stderr, and its outcome (:func:`graph_outcome`)."""
    def announce(opts) -> None:
        print(f"graph: ROS_DOMAIN_ID={opts.domain_id}, discovery {opts.discovery_range}; parameter files in "
              f"{out / 'params'}, node logs in {out / LOG_DIR}", file=sys.stderr)
        if external_sut:
            print(f"graph: waiting up to {opts.startup_timeout_s:g} s for your SUT node on /evoscen/commands/sut "
                  f"(ROS_DOMAIN_ID={opts.domain_id})", file=sys.stderr)

    result = run_graph_into(cfg, out, bag_dir, report_dir, domain_id=domain_id, overwrite=overwrite,
                            announce=announce, external_sut=external_sut, **options)
    return graph_outcome(result, cfg, out, bag_dir, report_dir)


def _inprocess_command(cfg, scenario, out: Path, bag_dir: Path | None, report_dir: Path, *, overwrite: bool,
                       plots: bool, quiet: bool, bag_writer: str) -> int:
    """``--mode inprocess``: the run with its progress bar (unless ``quiet``), its summary and scores; Ctrl-C
    ends it with a finished bag (status 130), a writer process that died with status 4."""
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_record.bag_writer import BagWriterError

    write_output(cfg, out, bag_dir, report_dir, overwrite=overwrite)
    bar = None
    if not quiet:
        from tqdm import tqdm

        # smoothing 0: the bar's rate is steps over its time, the summary's steps/s (step_bar)
        bar = tqdm(total=cfg.steps, unit="step", desc=f"{cfg.name} (inprocess)", file=sys.stderr, mininterval=0.5,
                   smoothing=0)
    try:
        summary = run_inprocess(cfg, bag_dir=bag_dir, scenario=scenario, report_dir=report_dir, plots=plots,
                                progress=step_bar(bar, cfg.steps) if bar else None, bag_writer=bag_writer)
    except KeyboardInterrupt:  # the run finished its bag first (run_end of kind interrupted)
        if bar is not None:
            bar.close()
            bar = None
        done = f": the bag {bag_dir} is finished" if bag_dir is not None else ""
        print(f"interrupted{done}", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BagWriterError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_NODE_DIED
    except (HostFault, PluginFault):
        if bar is not None:  # the error line on a line of its own
            bar.close()
            bar = None
        raise
    finally:
        if bar is not None:
            bar.close()
    for line in summary_lines(summary):
        print(line)
    if summary.bag_dir is not None:
        print(f"bag: {summary.bag_dir}  ({summary.message_count} messages, {summary.bag_bytes / 1e6:.2f} MB)")
    print_scores(report_dir)
    return EXIT_OK


def step_bar(bar, steps: int) -> Callable[[int], None]:
    """The in-process run's ``progress``: the bar's clock starts as step 0 begins (``progress(0)``) and the
    bar closes as the last step ends, so its rate is the summary's steps/s (``RunSummary.steps_wall_s``);
    scoring and the report come after it."""
    def tick(k: int) -> None:
        if k == 0:
            bar.reset(total=steps)
            return
        bar.update(1)
        if k == steps:
            bar.close()
    return tick


def summary_lines(summary) -> list[str]:
    """What an in-process run did (:class:`~evoscen_bringup.inprocess.RunSummary`), in words: its times, each
    measured once, and its events, each count saying whose it is."""
    close = (f"closing the bag: {summary.wall_time_s - summary.steps_wall_s:.2f} s, "
             if summary.bag_dir is not None else "")
    return [f"steps: {summary.steps}  simulated: {summary.sim_time_s:.1f} s  stepping: {summary.steps_wall_s:.2f} s "
            f"({summary.stepping_steps_per_s:.0f} steps/s, the progress bar's rate)  then {close}scoring and the "
            f"report: {summary.report_wall_s:.2f} s",
            f"all vehicles: collisions: {summary.collisions}  lane changes: {summary.lane_changes}  "
            f"re-entries: {summary.reentries}  off-road: {summary.off_road}; "
            f"the SUT: lane changes: {summary.sut_lane_changes} (completed)"]


def _checked_options(mode: str, out: str, domain_id: str | None, max_misses: str, deadline: float,
                     external_sut: bool, start_from: Path | None) -> tuple[Path, int | None, int]:
    """The command line's values checked in the order ``run_scenario.py`` checks them: ``--out``,
    ``--domain-id`` and ``--max-misses`` parsed, the options that need the other mode, ``--deadline``."""
    from evoscen_sim.limits import parse_cli_int, parse_cli_path

    path = parse_cli_path("--out", out)
    domain = parse_cli_int("--domain-id", domain_id, 0, 232) if domain_id is not None else None
    misses = parse_cli_int("--max-misses", max_misses, 1, 1_000_000)
    if external_sut and mode != "graph":
        raise InputError("--external-sut needs --mode graph (an external SUT node answers on the wire)")
    if start_from is not None and mode != "inprocess":
        raise InputError("--start-from: needs --mode inprocess (the node graph builds its world from the scenario file)")
    if mode == "graph" and not deadline > 0:
        raise InputError(f"--deadline = {deadline}: expected a number > 0 (s)")
    return path, domain, misses


def run_command(*, mode: str, config: Path | None, overrides: Mapping[str, str], out: str,
                start_from: Path | None = None, record: bool = True, overwrite: bool = False, plots: bool = True,
                quiet: bool = False, bag_writer: str = "auto", domain_id: str | None = None,
                discovery_range: str = "LOCALHOST", deadline: float = 2.0, max_misses: str = "5",
                wait_for: tuple[str, ...] = (), external_sut: bool = False) -> int:
    """``run_scenario.py``'s run (its docstring): the scenario file ``config`` (None: the shipped one) with
    ``overrides``, in ``mode``, into ``out``; returns the exit status. A plug-in that raised is one
    ``error:`` line here (status 3), with the line saying its bag is finished."""
    from evoscen_bringup.scenario import build_scenario
    from evoscen_sim.config.scenario_config import load_scenario_config

    out_dir, domain, misses = _checked_options(mode, out, domain_id, max_misses, deadline, external_sut, start_from)
    try:
        # everything the run needs is validated (config, map, SUT, spawn) before the output
        # directory is touched, so a bad input never costs an existing bag
        cfg = load_scenario_config(config, dict(overrides))
        bag_dir = None if not record or not cfg.recording.enabled else out_dir / "bag"
        if start_from is not None:  # docs/export.md "Starting evoscen from an exported scenario"
            from evoscen_bringup.scenario import build_scenario_from_start, load_road_of, start_overrides
            from evoscen_eval.scenes.scenario_export import initial_state_from_xosc

            start = initial_state_from_xosc(start_from, load_road_of(cfg))
            cfg = load_scenario_config(config, {**overrides, **start_overrides(start)})
            scenario = build_scenario_from_start(cfg, start)
        else:
            # without a bag one driver of all BVs: the same run (docs/performance.md "Experiments")
            scenario = build_scenario(cfg, partitioned=bag_dir is not None or mode == "graph")
        report_dir = out_dir / "report"
        if mode == "graph":
            if bag_dir is None:
                raise InputError("--mode graph always records (the evaluator node is part of the graph): "
                                 "drop --no-record / recording.enabled: false, or use --mode inprocess")
            return _graph_command(cfg, out_dir, bag_dir, report_dir, domain_id=domain, overwrite=overwrite,
                                  external_sut=external_sut, discovery_range=discovery_range, deadline_s=deadline,
                                  max_misses=misses, wait_for=tuple(wait_for), report_plots=plots)
        return _inprocess_command(cfg, scenario, out_dir, bag_dir, report_dir, overwrite=overwrite, plots=plots,
                                  quiet=quiet, bag_writer=bag_writer)
    except PluginFault as exc:  # a driver raised (docs/plugins.md §3): one line, a controller fault
        print(f"error: {exc}", file=sys.stderr)
        if exc.bag_dir is not None:
            print(f"aborted: the bag {exc.bag_dir} is finished ({exc.steps} world states); the run is not scored")
        return EXIT_FAULT
