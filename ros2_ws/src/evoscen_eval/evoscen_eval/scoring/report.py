"""The evaluation report of a run: ``report.json``, ``report.md`` and PNG plots.

Written the same way by the live evaluator node, by ``scripts/evaluate.py`` from a bag, and
by the in-process runner: :func:`write_stream_report` on the run's
:class:`~evoscen_eval.scoring.streaming.ScoreStream` (:func:`write_report` streams a
:class:`~evoscen_eval.scoring.rundata.RunData` through one). The plots read the stream's
:class:`~evoscen_eval.scoring.plot_inputs.PlotData`, bounded whatever the run's length.

Plots (matplotlib, Agg): the SUT's TTC distribution (``ttc.png``) and speed distribution
(``speed.png``); a timeline of speed, lane and TTC with exposures shaded and collisions
marked (``timeline.png``); the BVs within 100 m of the SUT over time with each 30-s window's mean
(``traffic.png``); a bird's-eye snapshot of the scene at each SUT collision
(``collision_<n>.png``, the first :data:`MAX_SNAPSHOTS`) and at the worst exposure
(``worst_exposure.png``); and a bird's-eye animation around the SUT (``run.gif``,
:mod:`evoscen_eval.scoring.animation`).

The words of ``report.md`` and of the printed score lines are :mod:`evoscen_eval.scoring.report_text`'s.
Each exposure is listed with the rules that made it one, their values and the vehicles involved
(:mod:`evoscen_eval.scoring.exposure_rules`); the worst-exposure snapshot's title and the exposure table
print the same entry of ``safety.exposure_list`` (:func:`exposure_caption`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from evoscen_sim.config.scenario_config import EvaluationConfig
from evoscen_sim.errors import HostFault, InputError

from evoscen_eval.scoring.animation import ANIMATION_FRAMES, write_animation
from evoscen_eval.scoring.exposure_rules import involved
from evoscen_eval.scoring.metrics import evaluate, report_of_stream, run_info, stream_run
from evoscen_eval.scoring.plot_inputs import SPEED_BINS, TTC_BINS, PlotData, Scene
from evoscen_eval.scoring.report_text import (  # noqa: F401 - report.md's words, read from here too
    comparative_line,
    exposure_caption,
    exposure_rows,
    markdown,
    score_line,
    score_lines,
    traffic_line,
)
from evoscen_eval.scoring.rundata import RunData, evaluation_settings_of
from evoscen_eval.scoring.streaming import ScoreStream
from evoscen_eval.scoring.sut_collisions import MAX_SNAPSHOTS

TTC_PLOT_MAX_S = float(TTC_BINS[-1])
"""TTC values above this (and infinite TTC: nothing closing ahead) are left out of the TTC plots."""


def evaluation_settings(run: RunData, override: EvaluationConfig | None = None) -> EvaluationConfig:
    """The evaluation settings of a run: ``override``, else the recorded scenario's, else the defaults."""
    return override if override is not None else evaluation_settings_of(run.scenario)


def report_of(run: RunData, override: EvaluationConfig | None = None) -> dict[str, Any]:
    """The ``report.json`` dict of a run."""
    return evaluate(run, evaluation_settings(run, override))


def write_report(run: RunData, out_dir: Path | str, *, override: EvaluationConfig | None = None,
                 plots: bool = True, source: str | None = None, animation_frames: int = ANIMATION_FRAMES
                 ) -> dict[str, Any]:
    """Score ``run`` and write ``report.json``, ``report.md`` and (``plots``) the PNGs and the
    animation of ``animation_frames`` frames (0: none) into ``out_dir``.

    Returns the report dict. InputError if ``out_dir`` cannot be written; HostFault if the disk is
    full or the file system read-only (:data:`~evoscen_sim.errors.HostFault.ERRNOS`).
    """
    stream = stream_run(run, evaluation_settings(run, override))
    return write_stream_report(stream, run_info(run), list(run.warnings), out_dir, plots=plots, source=source,
                               lane_segments=run.lane_segments, animation_frames=animation_frames)


def write_stream_report(stream: ScoreStream, info: dict[str, Any], warnings: list[str], out_dir: Path | str, *,
                        plots: bool = True, source: str | None = None,
                        lane_segments: np.ndarray | None = None,
                        animation_frames: int = ANIMATION_FRAMES) -> dict[str, Any]:
    """:func:`write_report` for a run scored as it streamed (``info``: :func:`~evoscen_eval.scoring.metrics.run_info_of`)."""
    report = report_of_stream(stream, info, warnings)
    if source is not None:
        report["run"]["source"] = source
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
        images = []
        if plots:
            plot = stream.plot_data(lane_segments)
            images = draw_plots(plot, stream.ev, report, out)
            if animation_frames > 0 and write_animation(plot.frames, lane_segments, report, out / ANIMATION_FILE,
                                                        frames=animation_frames):
                images.append(ANIMATION_FILE)
        (out / "report.json").write_text(json.dumps(report, indent=2, allow_nan=False) + "\n", encoding="utf-8")
        (out / "report.md").write_text(markdown(report, images, stream.ev), encoding="utf-8")
    except OSError as exc:
        if exc.errno in HostFault.ERRNOS:  # a full disk, a read-only file system: the host's, not the input's
            raise HostFault.of(exc, exc.filename or out) from None
        raise InputError(f"report directory {str(out)!r}: cannot write: {exc.strerror or exc}") from None
    return report


ANIMATION_FILE = "run.gif"
"""The report's bird's-eye animation (:mod:`evoscen_eval.scoring.animation`)."""

# ---------------------------------------------------------------------- plots


def draw_plots(plot: PlotData, ev: EvaluationConfig, report: dict[str, Any], out: Path) -> list[str]:
    """Draw the PNGs into ``out``; returns their file names."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names: list[str] = []
    closing = int(plot.ttc_hist.sum())
    fig, ax = plt.subplots(figsize=(6, 3.5))
    if closing:
        ax.stairs(plot.ttc_hist, TTC_BINS, fill=True, color="tab:blue")
    ax.axvline(ev.ttc_threshold_s, color="tab:red", ls="--", label=f"threshold {ev.ttc_threshold_s:g} s")
    ax.set(xlabel="SUT TTC to the vehicle ahead in its path (s)", ylabel="states",
           title=f"TTC distribution ({closing} of {plot.states} states closing within {TTC_PLOT_MAX_S:g} s)")
    ax.legend()
    names.append(_save(fig, out, "ttc.png"))

    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.stairs(plot.speed_hist, SPEED_BINS, fill=True, color="tab:green")
    ax.set(xlabel="SUT speed (m/s)", ylabel="states",
           title=f"Speed distribution (mean {report['efficiency']['mean_speed_mps']:.2f} m/s)")
    names.append(_save(fig, out, "speed.png"))

    t = plot.timeline_time_s
    fig, axes = plt.subplots(3, 1, figsize=(10, 6.5), sharex=True)
    axes[0].plot(t, plot.timeline_speed, lw=0.8)
    axes[0].set_ylabel("speed (m/s)")
    axes[1].step(t, plot.timeline_lane, where="post", lw=0.8)
    axes[1].set_ylabel("lane")
    from matplotlib.ticker import MaxNLocator

    axes[1].yaxis.set_major_locator(MaxNLocator(integer=True))
    axes[2].plot(t, np.minimum(plot.timeline_ttc, TTC_PLOT_MAX_S), lw=0.8)
    axes[2].axhline(ev.ttc_threshold_s, color="tab:red", ls="--", lw=0.8)
    axes[2].set(ylabel=f"TTC (s, ≤{TTC_PLOT_MAX_S:g})", xlabel="time (s)")
    dt = report["run"]["dt_s"]
    t0 = float(t[0]) if t.size else 0.0
    spans = exposure_spans(report, t0)
    for a, b in spans:
        for ax in axes:
            ax.axvspan(a, b, color="tab:orange", alpha=0.35, lw=0)
    if spans:  # a marker above each exposure: visible whatever the run's length
        axes[0].plot([(a + b) / 2 for a, b in spans], [1.0] * len(spans), "v", color="tab:orange", ms=7,
                     transform=axes[0].get_xaxis_transform(), clip_on=False, label="exposure")
    for col in report["safety"]["collision_list"]:
        for ax in axes:
            ax.axvline(col["time_s"], color="tab:red", lw=1.2)
    onsets = (report.get("challenge") or {}).get("onsets", [])  # docs/challenges.md
    for o in onsets:
        for ax in axes:
            ax.axvline(o["time_s"], color="tab:blue", ls=":", lw=1.2)
    starts = lane_change_marks(report, t0, t, plot.timeline_lane)
    for direction, marker, colour in ((1, "^", "tab:green"), (-1, "v", "tab:purple")):
        pts = [(tm, lane) for tm, lane, d in starts if d == direction]
        if pts:
            axes[1].plot(*zip(*pts), marker, color=colour, ms=4, ls="none",
                         label="SUT lane change " + ("left" if direction > 0 else "right"))
    if starts:
        axes[1].legend(loc="upper right", fontsize=7)
    every = "" if plot.timeline_stride == 1 else f"; one point per {plot.timeline_stride} states, lowest TTC"
    axes[0].set_title(f"SUT timeline: {report['safety']['exposures']} exposures (shaded, ▼; at least "
                      f"{100 * MIN_SPAN_SHARE:g} % of the axis wide), {len(starts)} SUT lane changes started (▲ left, ▼ right), "
                      f"{report['safety']['collisions']} collisions (red)"
                      f"{every}" + (f"\n{len(onsets)} challenges: the SUT's leader braking hard (blue, dotted)"
                                    if onsets else ""), fontsize=9)
    names.append(_save(fig, out, "timeline.png"))

    if "traffic" in report:
        names.append(_traffic_plot(plt, plot, report["traffic"], dt, out))

    for n, col in enumerate(report["safety"]["collision_list"][:MAX_SNAPSHOTS], 1):
        scene = plot.collision_scenes.get(min(int(col["state"]), plot.states - 1))
        if scene is not None:
            names.append(_snapshot(plt, scene, plot.lane_segments, set(col["ids"]),
                                   f"collision {n} at t = {col['time_s']:.1f} s", out, f"collision_{n}.png"))
    if plot.worst_scene is not None:
        w = plot.worst_scene
        n, x = worst_exposure_of(report, w.state)
        names.append(_snapshot(plt, w, plot.lane_segments, set(involved(x)) if x else set(),
                               worst_exposure_title(report, w.state, w.time_s), out, "worst_exposure.png"))
    return names


MIN_SPAN_SHARE = 0.004
"""An exposure's span on the timeline is at least this share of the run's duration wide (0.4 %: 1.2 s of a
300-s run), so a one-state exposure is not a hairline."""


def exposure_spans(report: dict[str, Any], t0: float = 0.0) -> list[tuple[float, float]]:
    """Each exposure's (start, end) on the timeline (s): its states, widened about their middle to at
    least :data:`MIN_SPAN_SHARE` of the run's duration and clamped to the run."""
    dt, duration = report["run"]["dt_s"], report["run"]["duration_s"]
    last = t0 + duration
    width = MIN_SPAN_SHARE * duration
    out = []
    for x in report["safety"]["exposure_list"]:
        a, b = x["start_time_s"], min(x["start_time_s"] + x["states"] * dt, last)
        if b - a < width:
            mid = (a + b) / 2
            a, b = max(t0, mid - width / 2), min(last, mid + width / 2)
        out.append((a, b))
    return out


def lane_change_marks(report: dict[str, Any], t0: float, times: np.ndarray, lanes: np.ndarray
                      ) -> list[tuple[float, float, int]]:
    """The SUT's lane changes as (time of the first state, lane there, +1 left / -1 right), from
    ``safety.conflicts.lane_change_pet`` (one entry per change; none in a report without it); the
    lane and so the direction (towards the target lane) from the timeline's point at that time."""
    dt = report["run"]["dt_s"]
    out = []
    for c in (report["safety"].get("conflicts") or {}).get("lane_change_pet", []):
        tm = t0 + int(c["start_state"]) * dt
        i = max(0, int(np.searchsorted(times, tm + 1e-9, side="right")) - 1)
        lane = float(lanes[i]) if len(lanes) else float(c["target_lane"])
        out.append((tm, lane, 1 if int(c["target_lane"]) > lane else -1))
    return out


def worst_exposure_of(report: dict[str, Any], state: int) -> tuple[int, dict[str, Any] | None]:
    """The exposure whose worst state is ``state`` and its number in report.md's table (1-based)."""
    for n, x in enumerate(report["safety"]["exposure_list"], 1):
        if int(x["worst_state"]) == int(state):
            return n, x
    return 0, None


def worst_exposure_title(report: dict[str, Any], state: int, time_s: float) -> str:
    """The title of ``worst_exposure.png``: the exposure's entry in report.md's words (:func:`exposure_caption`)."""
    n, x = worst_exposure_of(report, state)
    head = f"worst exposure (no. {n} of report.md) at its most severe state, t = {time_s:.1f} s"
    return head + (": " + exposure_caption(x) if x else "")


def _traffic_plot(plt, plot: PlotData, tr: dict[str, Any], dt: float, out: Path) -> str:
    """``traffic.png``: BVs within the range of the SUT over time with each window's mean."""
    from matplotlib.ticker import MaxNLocator

    fig, ax = plt.subplots(figsize=(10, 3.5))
    t = plot.timeline_time_s
    per = "per state" if plot.timeline_stride == 1 else f"mean of each {plot.timeline_stride} states"
    ax.step(t, plot.timeline_bvs, where="post", lw=0.7, color="0.55", label=f"BVs within {tr['range_m']:g} m ({per})")
    for n, x in enumerate(tr["windows"]):
        end = x["start_time_s"] + x["states"] * dt
        label = ("last partial window's mean" if x["partial"] else
                 f"{tr['window_s']:g}-s window mean" if n == 0 else None)
        ax.hlines(x["mean_bvs"], x["start_time_s"], end, colors="tab:blue", lw=2.5, ls=":" if x["partial"] else "-",
                  label=label)
    ax.axhline(tr["mean_bvs"], color="tab:red", ls="--", lw=0.8, label=f"run mean {tr['mean_bvs']:.2f}")
    ax.set_ylim(bottom=-0.25)  # a count of 0 stays visible above the axis
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    low = tr["min_window_mean_bvs"]
    ax.set(xlabel="time (s)", ylabel="BVs",
           title=f"Traffic around the SUT: mean {tr['mean_bvs']:.2f} BVs within {tr['range_m']:g} m, lowest window "
                 f"{'–' if low is None else f'{low:.2f}'}, none in {100.0 * tr['empty_share']:.1f} % of states")
    ax.legend(loc="upper right", fontsize=8)
    return _save(fig, out, "traffic.png")


def _save(fig, out: Path, name: str) -> str:
    fig.tight_layout()
    fig.savefig(out / name, dpi=100)
    import matplotlib.pyplot as plt

    plt.close(fig)
    return name


def _snapshot(plt, scene: Scene, lane_segments: np.ndarray | None, highlight: set[int], title: str,
              out: Path, name: str) -> str:
    """Bird's-eye view around the SUT in ``scene``: lane lines, every vehicle as its box."""
    from matplotlib.collections import LineCollection
    from matplotlib.patches import Polygon

    c, sut = scene.columns, scene.sut_index
    cx, cy = c["x"][sut], c["y"][sut]
    half = 70.0
    fig, ax = plt.subplots(figsize=(10, 4))
    if lane_segments is not None and len(lane_segments):
        seg = lane_segments
        near = (np.abs(seg[:, :, 0] - cx).min(axis=1) < 2 * half) & (np.abs(seg[:, :, 1] - cy).min(axis=1) < 2 * half)
        ax.add_collection(LineCollection(seg[near], colors="0.6", linewidths=0.8))
    for j in range(scene.ids.shape[0]):
        x, y, yaw, length, width = (c[f][j] for f in ("x", "y", "yaw", "length", "width"))
        if abs(x - cx) > half + 10 or abs(y - cy) > half:
            continue
        ca, sa = math.cos(yaw), math.sin(yaw)
        corners = [(x + ca * u - sa * v, y + sa * u + ca * v)
                   for u, v in ((length / 2, width / 2), (-length / 2, width / 2),
                                (-length / 2, -width / 2), (length / 2, -width / 2))]
        vid = int(scene.ids[j])
        color = "orange" if j == sut else ("tab:red" if vid in highlight else "tab:blue")
        edge, lw = ("tab:red", 2.0) if vid in highlight else ("k", 0.5)
        ax.add_patch(Polygon(corners, closed=True, fc=color, ec=edge, lw=lw, alpha=0.85))
        ax.text(x, y + width, f"{vid}\n{c['speed'][j] * 3.6:.0f}", fontsize=6, ha="center", va="bottom")
    ax.set_xlim(cx - half, cx + half)
    ax.set_ylim(cy - 15, cy + 15)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    import textwrap

    wrapped = "\n".join(line for part in title.split("\n") for line in textwrap.wrap(part, 120))
    ax.set_title(f"{wrapped}\n(SUT orange, involved vehicles outlined red; ids, km/h)", fontsize=8)
    return _save(fig, out, name)
