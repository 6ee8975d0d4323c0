#!/usr/bin/env python3
"""Run an evoscen scenario, record it as a rosbag2 (MCAP) bag and score it.

    python scripts/run_scenario.py --mode inprocess [--config FILE] [--steps N] [--seed S]
                                   [--sut NAME] [--bvs N] [--mix C:M:K] [--out DIR]

The bag goes to ``DIR/bag/``, the report (report.json, report.md, plots) to ``DIR/report/``
and the resolved configuration to ``DIR/scenario.yaml``.
``--config`` defaults to the shipped scenario; ``--steps``, ``--seed``, ``--sut``,
``--bvs`` and ``--mix`` override the config's keys (with the same validation). Bad input
prints one line ``error: ...`` and exits with status 2. Ctrl-C ends the run with a finished bag
(its last event ``run_end`` of kind ``interrupted``) and status 130; in-process runs write the
bag inline or in a writer process (``--bag-writer``, docs/recording.md), the same bytes. An
output that cannot be written (a full disk, a read-only or removed output directory) stops the
run at the next step boundary with one line ``error: cannot write FILE: CAUSE; ...`` saying what
became of the bag and what to do, and status 5.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen_contract.contract import (
    EXIT_BAD_INPUT,
    EXIT_FAULT,
    EXIT_HOST_FAULT,
    EXIT_INTERRUPTED,
    EXIT_NODE_DIED,
    EXIT_OK,
    TOPIC_WORLD,
)
from evoscen_bringup.output import prepare_output

MODES = ("graph", "inprocess")
ABORTED = (EXIT_BAD_INPUT, EXIT_FAULT, EXIT_NODE_DIED)
"""Statuses of a graph run that ended early (a refused answer, a controller fault, a dead node): no score."""


def add_scenario_options(ap: argparse.ArgumentParser) -> None:
    """The scenario options (``--config`` and the key overrides), shared with graph_node.py."""
    ap.add_argument("--config", type=Path, default=None, help="scenario YAML (default: the shipped default)")
    ap.add_argument("--steps", help="number of steps (overrides 'steps')")
    ap.add_argument("--seed", help="random seed (overrides 'seed')")
    ap.add_argument("--sut", help="SUT model name (overrides 'sut.model')")
    ap.add_argument("--bvs", help="number of background vehicles (overrides 'bvs.count')")
    ap.add_argument("--mix", help="policy mix competitive:mutual:cooperative, e.g. 4:3:3 (overrides 'bvs.mix')")
    ap.add_argument("--bv-nodes", help="BV nodes: by_policy, single or a number N (overrides 'bvs.nodes'; "
                    "docs/architecture.md §5, \"BV nodes\")")


def scenario_overrides(args: argparse.Namespace) -> dict[str, str]:
    """The configuration keys the scenario options override (only those given)."""
    return {key: value for key, value in (
        ("steps", args.steps), ("seed", args.seed), ("sut.model", args.sut),
        ("bvs.count", args.bvs), ("bvs.mix", args.mix), ("bvs.nodes", args.bv_nodes)) if value is not None}


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="run_scenario.py", description=__doc__.split("\n\n")[0])
    from evoscen import __version__

    ap.add_argument("--version", action="version", version=f"evoscen {__version__}")
    ap.add_argument("--mode", default="graph", choices=MODES,
                    help="graph (default): one ROS 2 process per node, lockstep; inprocess: all cores in one process, "
                         "no middleware")
    add_scenario_options(ap)
    ap.add_argument("--start-from", type=Path, default=None, metavar="FILE.xosc",
                    help="start from the initial state of an exported OpenSCENARIO file (its vehicles, lanes, "
                    "positions, speeds and sizes) instead of the spawn layout; --mode inprocess (docs/export.md)")
    ap.add_argument("--list-suts", action="store_true",
                    help="list the installed SUT models (name, built-in or entry point package, description) and exit")
    ap.add_argument("--list-mutants", action="store_true",
                    help="list the SUT mutants (name, class, the SUT models they apply to, description) and exit")
    ap.add_argument("--out", default="runs/latest", help="output directory (default runs/latest)")
    ap.add_argument("--no-record", action="store_true", help="do not record a bag")
    ap.add_argument("--overwrite", action="store_true", help="replace an existing bag in OUT/bag and report in OUT/report")
    ap.add_argument("--no-plots", action="store_true", help="report.json and report.md only, no PNG plots")
    ap.add_argument("--quiet", action="store_true", help="no progress bar (inprocess)")
    ap.add_argument("--bag-writer", default="auto", choices=("auto", "inline", "process"),
                    help="inprocess: write the bag between the steps (inline) or in a forked writer process "
                         "(process), the same bytes; auto (default): process when more than one CPU is usable "
                         "(docs/recording.md)")
    g = ap.add_argument_group("graph mode")
    g.add_argument("--domain-id", help="ROS_DOMAIN_ID of the nodes (default: a free one of 1..100, drawn at random; "
                   "no two evoscen graphs on one host share a domain)")
    g.add_argument("--discovery-range", default="LOCALHOST", choices=("LOCALHOST", "SUBNET", "SYSTEM_DEFAULT"),
                   help="ROS_AUTOMATIC_DISCOVERY_RANGE: SUBNET lets ROS 2 machines on the network see the topics")
    g.add_argument("--deadline", type=float, default=2.0, help="per-step controller deadline in seconds (default 2.0)")
    g.add_argument("--max-misses", default="5", help="consecutive missed deadlines that abort (default 5)")
    g.add_argument("--wait-for", nargs="+", default=[], metavar="NODE",
                   help="node names of your own nodes (a monitor, a bridge) to wait for before step 0, "
                        "so they receive every step; a BV node of the scenario named here (evoscen_bv_mutual) "
                        "is not started: start it by hand with OUT/params/<name>.yaml (docs/architecture.md §5)")
    g.add_argument("--external-sut", action="store_true",
                   help="do not start evoscen's SUT node: your own node answers on /evoscen/commands/sut "
                        "(see examples/README.md)")
    return ap.parse_args(argv)


def print_scores(report_dir: Path) -> None:
    """One line of scores from ``report_dir/report.json`` and where the report is."""
    import json

    path = report_dir / "report.json"
    if not path.is_file():
        print(f"error: no report was written ({path} is missing)", file=sys.stderr)
        return
    r = json.loads(path.read_text(encoding="utf-8"))
    from evoscen_eval.scoring.report import score_line

    print(score_line(r))
    d = r.get("comparative")
    if d:  # docs/evaluation.md §10
        print(f"comparative: {d['score']:.4f} (progress {d['progress']['score']:.4f}, safety {d['safety']['score']:.4f}, "
              f"lane-change time {d['lane_change_time']['score']:.4f}, interaction {d['interaction']['score']:.4f})")
    for warning in r["warnings"]:
        print(f"warning: {warning}", file=sys.stderr)
    print(f"report: {report_dir / 'report.md'}")


def run_graph_mode(args: argparse.Namespace, cfg, out: Path, bag_dir: Path, report_dir: Path,
                   domain: int) -> int:
    """Run the node graph on ``domain`` (reserved by the caller); print the outcome; return its status."""
    from evoscen_bringup.graph_runner import GraphOptions, run_graph
    from evoscen_record.bag_reader import open_bag_reader
    from evoscen_sim.errors import InputError

    opts = GraphOptions(domain_id=domain, discovery_range=args.discovery_range,
                        deadline_s=args.deadline, max_misses=args.max_misses, external_sut=args.external_sut,
                        wait_for=tuple(args.wait_for), report_dir=report_dir, report_plots=not args.no_plots)
    print(f"graph: ROS_DOMAIN_ID={domain}, discovery {opts.discovery_range}; parameter files in {out / 'params'}",
          file=sys.stderr)
    if args.external_sut:
        print(f"graph: waiting up to {opts.startup_timeout_s:g} s for your SUT node on /evoscen/commands/sut "
              f"(ROS_DOMAIN_ID={domain})", file=sys.stderr)
    result = run_graph(cfg, out, bag_dir, opts)
    if result.status == EXIT_HOST_FAULT:  # the recorder said in one line what became of the bag
        return result.status
    counts: dict[str, int] = {}
    if not any(bag_dir.glob("*.mcap")) if bag_dir.is_dir() else True:
        # an error line only when no node said one (a failed run has said why in its own line)
        print(f"{'error: ' if result.status == EXIT_OK else ''}no bag was written in {bag_dir} "
              "(the run ended during start-up)", file=sys.stderr)
        return result.status or EXIT_FAULT
    try:
        for topic, _type, _t, _data in open_bag_reader(bag_dir):
            counts[topic] = counts.get(topic, 0) + 1
    except InputError as exc:
        print(f"error: the bag is not readable ({exc}); if the recorder was killed, recover what it wrote with: "
              f"python scripts/reindex.py {bag_dir}", file=sys.stderr)
        return result.status or EXIT_FAULT
    steps = max(counts.get(TOPIC_WORLD, 1) - 1, 0)
    print(f"steps: {steps}  domain: {result.domain_id}  wall: {result.wall_time_s:.2f} s  "
          f"nodes: " + ", ".join(f"{n}={s}" for n, s in result.node_status.items()))
    size = sum(f.stat().st_size for f in bag_dir.iterdir())
    print(f"bag: {bag_dir}  ({sum(counts.values())} messages, {size / 1e6:.2f} MB)")
    if result.status in ABORTED:  # a controller fault or a dead node ended the run early: not scored
        print(f"aborted: the run ended at step {steps} of {cfg.steps} (exit status {result.status}); "
              "the run is not scored")
        return result.status
    print_scores(report_dir)
    return result.status


def list_suts() -> list[str]:
    """One line per SUT model: name, where it comes from, description; then the entry points that failed to load."""
    from evoscen_sim.model_registry import broken_plugins, get_model, model_names, model_source

    names = model_names("sut")
    rows = [(n, model_source(n), get_model(n, "sut").description) for n in names]
    width = [max(len(r[i]) for r in rows) for i in (0, 1)]
    lines = [f"{n:<{width[0]}}  {src:<{width[1]}}  {desc}".rstrip() for n, src, desc in rows]
    lines += [f"{n:<{width[0]}}  failed to load: {why}" for n, why in sorted(broken_plugins().items())]
    return lines


def list_mutants() -> list[str]:
    """One line per mutant of the library (``evoscen_sut.mutants``): name, class, the SUT models it
    applies to, description (its first sentence)."""
    import inspect

    from evoscen_sim.model_registry import model_names
    from evoscen_sut import mutants

    every = [n for n in model_names("sut") if n != "mutant"]
    # where the library says which bases a mutant applies to: a ``bases`` field of the mutant, or a
    # function of the library named for it (``applicable_bases(name)``, ``applies_to(name)``, ...);
    # without either, every SUT model but ``mutant`` (mutant.py's base choices)
    applies = next((f for n, f in inspect.getmembers(mutants, inspect.isfunction)
                    if not n.startswith("_") and ("applic" in n or "applies" in n or n.startswith("bases"))
                    and len(inspect.signature(f).parameters) >= 1), None)
    lines = []
    for m in mutants.LIBRARY.values():
        bases = list(getattr(m, "bases", None) or every)
        if applies is not None:
            try:  # applies(name) -> the bases, or applies(name, base) -> whether it applies
                two = len(inspect.signature(applies).parameters) >= 2
                bases = [b for b in every if applies(m.name, b)] if two else list(applies(m.name))
            except Exception:  # noqa: BLE001 - a listing never fails on it: every base
                bases = every
        bases = [b for b in bases if b in every] if bases else bases
        desc = m.description.split(": ")[0].split(". ")[0].rstrip(".")
        lines.append((m.name, "built-in (evoscen_sut.mutants)", m.klass,
                      "bases: " + (", ".join(bases) if bases != every else f"any SUT model ({len(every)})"), desc))
    width = [max(len(r[i]) for r in lines) for i in range(4)]
    return [f"{a:<{width[0]}}  {b:<{width[1]}}  {c:<{width[2]}}  {d:<{width[3]}}  {e}" for a, b, c, d, e in lines]


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if args.list_suts or args.list_mutants:
        print("\n".join(list_suts() if args.list_suts else list_mutants()))
        return EXIT_OK
    from evoscen_bringup.domains import reserve_domain
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_bringup.scenario import build_scenario
    from evoscen_record.bag_writer import BagWriterError
    from evoscen_sim.limits import parse_cli_int, parse_cli_path
    from evoscen_sim.config.scenario_config import dump_config, load_scenario_config
    from evoscen_sim.errors import HostFault, InputError, PluginFault

    try:
        args.out = parse_cli_path("--out", args.out)
        if args.domain_id is not None:
            args.domain_id = parse_cli_int("--domain-id", args.domain_id, 0, 232)
        args.max_misses = parse_cli_int("--max-misses", args.max_misses, 1, 1_000_000)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    overrides = scenario_overrides(args)
    if args.external_sut and args.mode != "graph":
        print("error: --external-sut needs --mode graph (an external SUT node answers on the wire)", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.start_from is not None and args.mode != "inprocess":
        print("error: --start-from: needs --mode inprocess (the node graph builds its world from the scenario file)",
              file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.mode == "graph":
        for name, value, ok in (("--domain-id", args.domain_id, args.domain_id is None or 0 <= args.domain_id <= 232),
                                ("--deadline", args.deadline, args.deadline > 0),
                                ("--max-misses", args.max_misses, args.max_misses >= 1)):
            if not ok:
                print(f"error: {name} = {value}: expected " + {"--domain-id": "an integer in [0, 232]",
                      "--deadline": "a number > 0 (s)", "--max-misses": "an integer >= 1"}[name], file=sys.stderr)
                return EXIT_BAD_INPUT
    try:
        # everything the run needs is validated (config, map, SUT, spawn) before the output
        # directory is touched, so a bad input never costs an existing bag
        cfg = load_scenario_config(args.config, overrides)
        out = args.out
        bag_dir = None if args.no_record or not cfg.recording.enabled else out / "bag"
        if args.start_from is not None:  # docs/export.md "Starting evoscen from an exported scenario"
            from evoscen_bringup.scenario import build_scenario_from_start, load_road_of, start_overrides
            from evoscen_eval.scenes.scenario_export import initial_state_from_xosc

            start = initial_state_from_xosc(args.start_from, load_road_of(cfg))
            cfg = load_scenario_config(args.config, {**overrides, **start_overrides(start)})
            scenario = build_scenario_from_start(cfg, start)
        else:
            # without a bag one driver of all BVs: the same run (docs/performance.md "Experiments")
            scenario = build_scenario(cfg, partitioned=bag_dir is not None or args.mode == "graph")
        if args.mode == "graph" and bag_dir is None:
            raise InputError("--mode graph always records (the evaluator node is part of the graph): "
                             "drop --no-record / recording.enabled: false, or use --mode inprocess")
        report_dir = out / "report"
        if args.mode == "graph":
            # the domain is reserved (docs/architecture.md) before the output directory is touched,
            # and held until the graph has ended
            with reserve_domain(args.domain_id) as domain:
                prepare_output(out, bag_dir, report_dir, overwrite=args.overwrite)
                try:
                    dump_config(cfg, out / "scenario.yaml")
                    return run_graph_mode(args, cfg, out, bag_dir, report_dir, domain)
                except OSError as exc:  # scenario.yaml, the parameter files: before step 0
                    raise HostFault.of(exc, exc.filename or out) from None
        prepare_output(out, bag_dir, report_dir, overwrite=args.overwrite)
        try:
            dump_config(cfg, out / "scenario.yaml")
        except OSError as exc:
            raise HostFault.of(exc, out / "scenario.yaml") from None
        bar = None
        if not args.quiet:
            from tqdm import tqdm

            bar = tqdm(total=cfg.steps, unit="step", desc=f"{cfg.name} ({args.mode})", file=sys.stderr, mininterval=0.5)
        try:
            summary = run_inprocess(cfg, bag_dir=bag_dir, scenario=scenario, report_dir=report_dir,
                                    plots=not args.no_plots, progress=(lambda k: bar.update(1)) if bar else None,
                                    bag_writer=args.bag_writer)
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
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except HostFault as exc:
        print(f"error: {exc.line()}", file=sys.stderr)
        return EXIT_HOST_FAULT
    except PluginFault as exc:  # a driver raised (docs/plugins.md §3): one line, a controller fault
        print(f"error: {exc}", file=sys.stderr)
        if exc.bag_dir is not None:
            print(f"aborted: the bag {exc.bag_dir} is finished ({exc.steps} world states); the run is not scored")
        return EXIT_FAULT
    print(f"steps: {summary.steps}  simulated: {summary.sim_time_s:.1f} s  wall: {summary.wall_time_s:.2f} s  "
          f"({summary.steps_per_s:.0f} steps/s)")
    print(f"collisions: {summary.collisions}  lane changes: {summary.lane_changes}  re-entries: {summary.reentries}  "
          f"off-road: {summary.off_road}")
    if summary.bag_dir is not None:
        print(f"bag: {summary.bag_dir}  ({summary.message_count} messages, {summary.bag_bytes / 1e6:.2f} MB)")
    print_scores(report_dir)
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
