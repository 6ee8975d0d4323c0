"""The fidelity experiment (docs/method.md §5.3, §6.3): our runs' behaviour against naturalistic HighD data.

Both sides go through :func:`evoscen_eval.naturalistic.behaviour.extract_behaviour`: HighD recordings as
loaded (:func:`evoscen_eval.naturalistic.highd.load_recording`), our bags through
:func:`evoscen_eval.scoring.rundata.read_run` and :func:`evoscen_eval.naturalistic.highd_export.run_to_highd` at
their own rate (no resampling). The four distributions (:data:`DISTRIBUTIONS`) are compared
with :func:`evoscen_eval.naturalistic.similarity.compare`; the result is a table (CSV and Markdown) and
four plots: the (DHW, speed) and (THW, speed) joint KDEs side by side, the mandatory TTC and
voluntary speed KDEs overlaid.
"""

from __future__ import annotations

import csv
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from evoscen_sim.errors import InputError

from evoscen_eval.naturalistic.behaviour import BehaviourConfig, BehaviourSamples, extract_behaviour
from evoscen_eval.naturalistic.highd import load_recording
from evoscen_eval.naturalistic.highd_export import ExportOptions, VirtualRoad, run_to_highd
from evoscen_eval.naturalistic.similarity import Comparison, KdeConfig, KdeError, compare


@dataclass(frozen=True)
class Distribution:
    """One of the four compared distributions."""

    key: str
    title: str
    attribute: str
    """Field of :class:`~evoscen_eval.naturalistic.behaviour.BehaviourSamples` holding the samples."""
    axis_labels: tuple[str, ...]


DISTRIBUTIONS: tuple[Distribution, ...] = (
    Distribution("dhw_speed", "Car following: DHW and speed", "dhw_speed", ("DHW (m)", "speed (m/s)")),
    Distribution("thw_speed", "Car following: THW and speed", "thw_speed", ("THW (s)", "speed (m/s)")),
    Distribution("mandatory_ttc", "Mandatory lane change: TTC", "mandatory_ttc_s", ("TTC (s)",)),
    Distribution("voluntary_speed", "Voluntary lane change: speed", "voluntary_speed_mps", ("speed (m/s)",)),
)


@dataclass
class FidelityRow:
    """One distribution's result; ``comparison`` None when a side has too few samples."""

    distribution: Distribution
    n_naturalistic: int
    n_simulated: int
    comparison: Comparison | None
    note: str = ""

    @property
    def js(self) -> float | None:
        return None if self.comparison is None else self.comparison.js

    @property
    def similarity_pct(self) -> float | None:
        return None if self.comparison is None else self.comparison.similarity_pct


def road_for_run(run) -> tuple[VirtualRoad, list[str]]:  # a RunData
    """The virtual road of a run's export: lanes, lane width and length of the map it ran on.

    The map is the recorded scenario's ``map``; if that path does not exist here (a bag from
    another machine), the map of the same file name shipped with evoscen_sim; otherwise the
    defaults of :class:`VirtualRoad` (the shipped on-ramp), with a warning.
    """
    from evoscen_sim.config.scenario_config import share_path
    from evoscen_sim.road.road_model import load_road

    ref = (run.scenario or {}).get("map")
    candidates = []
    if ref:
        candidates.append(Path(ref))
        try:
            candidates.append(share_path(f"maps/{Path(ref).name}"))
        except InputError:
            pass
    for path in candidates:
        if path.is_file():
            try:
                road = load_road(path)
            except InputError:
                continue
            vmax = float(np.asarray(road.speed_limit_max_mps(road.num_lanes - 1, 0.0)))
            return VirtualRoad(num_lanes=int(road.num_lanes), lane_width_m=float(road.lane_width_m),
                               length_m=float(road.length_m),
                               speed_limit_mps=vmax if np.isfinite(vmax) else -1.0), []
    return VirtualRoad(), [f"the run's map ({ref or 'not recorded'}) is not available here: exported on the "
                           "shipped on-ramp's virtual road (5 lanes of 3.5 m, 2393.76 m)"]


def run_recording(bag_dir: Path | str, options: ExportOptions = ExportOptions(frame_rate_hz=None)):
    """A bag's run as a HighD recording (``options.road`` replaced by the run's own road)."""
    from dataclasses import replace

    from evoscen_eval.scoring.rundata import read_run

    run = read_run(bag_dir)
    road, warnings = road_for_run(run)
    rec = run_to_highd(run, replace(options, road=road))
    rec.source = str(bag_dir)
    rec.warnings = [*run.warnings, *warnings]
    return rec


def export_bag(bag: Path, outdir: Path, *, recording_id: str = "1", frame_rate: str = "25",
               overwrite: bool = False) -> None:
    """``scripts/export_highd.py``: write a bag's run as HighD's three files in ``outdir`` (docs/experiments.md
    §3), at ``frame_rate`` Hz under ``recording_id`` (texts, checked here); prints the readers' warnings
    (stderr) and one line of what it wrote. Bad input: one :class:`InputError` line."""
    import sys

    from evoscen_eval.naturalistic.highd import write_recording

    if not recording_id.isdigit() or not 1 <= int(recording_id) <= 99:
        raise InputError(f"--recording-id {recording_id!r}: expected an integer in [1, 99]")
    try:
        rate = float(frame_rate)
    except ValueError:
        rate = float("nan")
    if not 0 < rate <= 1000:
        raise InputError(f"--frame-rate {frame_rate!r}: expected a number of frames per second in (0, 1000]")
    rec = run_recording(bag, ExportOptions(frame_rate_hz=rate, recording_id=int(recording_id)))
    for w in rec.warnings:
        print(f"warning: {w}", file=sys.stderr)
    paths = write_recording(outdir, rec, overwrite=overwrite)
    n_sut = int((rec.tracks_meta["evoscenRole"] == 1).sum())
    print(f"exported {bag} -> {paths['tracks'].parent}: {rec.num_rows} rows, {len(rec.tracks_meta['id'])} tracks "
          f"({n_sut} of the SUT), {int(rec.tracks['frame'].max())} frames at {rec.frame_rate_hz:g} Hz")


def bag_samples(bags: Iterable[Path | str], config: BehaviourConfig = BehaviourConfig()) -> tuple[BehaviourSamples, list[str]]:
    """Behaviour samples of our bags (BVs only unless ``config.include_sut``) and the readers' warnings."""
    parts, warnings = [], []
    for bag in bags:
        rec = run_recording(bag)
        warnings.extend(rec.warnings)
        parts.append(extract_behaviour(rec, config))
    return BehaviourSamples.concat(parts), warnings


def highd_samples(directory: Path | str, recordings: Iterable[str],
                  config: BehaviourConfig = BehaviourConfig()) -> BehaviourSamples:
    """Behaviour samples of HighD recordings, one recording in memory at a time."""
    return BehaviourSamples.concat([extract_behaviour(load_recording(directory, r), config) for r in recordings])


def compare_behaviour(naturalistic: BehaviourSamples, simulated: BehaviourSamples,
                      kde: KdeConfig = KdeConfig()) -> list[FidelityRow]:
    """JS divergence and similarity of the four distributions (docs/method.md §5.3)."""
    rows = []
    for dist in DISTRIBUTIONS:
        a = getattr(naturalistic, dist.attribute)
        b = getattr(simulated, dist.attribute)
        try:
            rows.append(FidelityRow(dist, len(a), len(b), compare(a, b, kde)))
        except KdeError as exc:
            rows.append(FidelityRow(dist, len(a), len(b), None, f"not compared: {exc}"))
    return rows


def _fmt(value: float | None, digits: int) -> str:
    return "n/a" if value is None else f"{value:.{digits}f}"


def write_csv(rows: list[FidelityRow], path: Path) -> None:
    """``distribution, n_naturalistic, n_simulated, js, similarity_pct, note``."""
    with open(path, "w", encoding="utf-8", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["distribution", "n_naturalistic", "n_simulated", "js", "similarity_pct", "note"])
        for r in rows:
            w.writerow([r.distribution.key, r.n_naturalistic, r.n_simulated, _fmt(r.js, 6),
                        _fmt(r.similarity_pct, 3), r.note])


def markdown_table(rows: list[FidelityRow], naturalistic: BehaviourSamples | None = None,
                   simulated: BehaviourSamples | None = None) -> str:
    """The fidelity table as Markdown (with the lane-change counts when the samples are given)."""
    out = ["| distribution | HighD samples | simulated samples | JS divergence | similarity |",
           "|---|---:|---:|---:|---:|"]
    for r in rows:
        sim = "n/a" if r.similarity_pct is None else f"{r.similarity_pct:.2f} %"
        out.append(f"| {r.distribution.title} | {r.n_naturalistic} | {r.n_simulated} | {_fmt(r.js, 4)} | {sim} |")
    notes = [f"- {r.distribution.title}: {r.note}" for r in rows if r.note]
    for name, smp in (("HighD", naturalistic), ("simulation", simulated)):
        if smp is not None:
            notes.append(f"- {name}: {smp.num_mandatory} mandatory lane changes ({len(smp.mandatory_ttc_s)} with a "
                         f"TTC in the distribution's range), {smp.num_voluntary} voluntary")
    return "\n".join(out + ([""] + notes if notes else [])) + "\n"


def plot_rows(rows: list[FidelityRow], out_dir: Path) -> list[Path]:
    """The four plots of docs/method.md §5.3 as PNG (joint KDEs side by side; 1-D KDEs overlaid)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    for r in rows:
        c = r.comparison
        path = out_dir / f"{r.distribution.key}.png"
        if c is None:  # still a figure, saying why there is no KDE
            fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
            ax.axis("off")
            ax.text(0.5, 0.5, f"{r.distribution.title}\n\nHighD samples: {r.n_naturalistic}, simulated samples: "
                    f"{r.n_simulated}\n{r.note}", ha="center", va="center", wrap=True)
            fig.savefig(path, dpi=110)
            plt.close(fig)
            written.append(path)
            continue
        title = f"{r.distribution.title} — JS {c.js:.4f}, similarity {c.similarity_pct:.2f} %"
        if len(c.axes) == 2:
            fig, axs = plt.subplots(1, 2, figsize=(11, 4.5), sharex=True, sharey=True, constrained_layout=True)
            vmax = max(c.p.max(), c.q.max())
            for ax, pmf, name, n in ((axs[0], c.p, "HighD", c.n_p), (axs[1], c.q, "simulation", c.n_q)):
                mesh = ax.pcolormesh(c.axes[0], c.axes[1], pmf.T, shading="auto", cmap="viridis", vmin=0, vmax=vmax)
                ax.set_title(f"{name}, {n} samples")
                ax.set_xlabel(r.distribution.axis_labels[0])
            axs[0].set_ylabel(r.distribution.axis_labels[1])
            fig.colorbar(mesh, ax=axs, label="probability per grid cell")
        else:
            fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
            x = c.axes[0]
            step = x[1] - x[0]
            ax.plot(x, c.p / step, label=f"HighD ({c.n_p})")
            ax.plot(x, c.q / step, label=f"simulation ({c.n_q})")
            ax.set_xlabel(r.distribution.axis_labels[0])
            ax.set_ylabel("density")
            ax.legend()
        fig.suptitle(title)
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    return written
