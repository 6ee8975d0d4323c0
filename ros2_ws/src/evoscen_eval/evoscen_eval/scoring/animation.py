"""A run to watch: a bird's-eye animation of the road around the SUT (``run.gif``), written beside
every report and every critical-event clip (docs/evaluation.md §7.1).

:class:`FrameSeries` keeps, block by block, one state in every ``stride`` with the vehicles within
:data:`WINDOW_M` of the SUT along x (the SUT's lane-change flag of the ``stride`` states it stands
for is kept with it); past :data:`KEEP_FRAMES` frames it drops every other and doubles the stride,
as the report's timeline does, so its memory is bounded whatever the run's length.
:func:`write_animation` draws ``frames`` of them (evenly spread) with Pillow directly, on a fixed
palette, and saves them as a GIF (fast and small: docs/evaluation.md §7.1).

What a frame shows: lane lines; every vehicle as its box (its own length and width, so a truck
is as long as it is), filled by role and driver model (:data:`POLICY_COLOURS`; the SUT orange) — a truck BV
(longer than :data:`~evoscen_contract.contract.TRUCK_MIN_LENGTH_M`) olive with a line along its length, whatever
the policy code its slot carries; a pointer from the SUT towards the side it changes lanes to
(while it changes lanes in the states the frame stands for); during an exposure (or a collision) in
those states the SUT and the vehicles its rules name outlined magenta (red is a competitive BV's
fill) and the rules in the title.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from evoscen_contract import contract as C

WINDOW_M = 80.0
"""Half-width of the view around the SUT along x (m)."""
KEEP_FRAMES = 400
"""Most frames :class:`FrameSeries` keeps (a longer run is kept at a doubled stride)."""
ANIMATION_FRAMES = 120
"""Frames drawn by default (:func:`write_animation`'s ``frames``; ``--animation-frames``)."""
FRAME_MS = 100
"""Each frame's display time (ms)."""
TRUCK_LENGTH_M = C.TRUCK_MIN_LENGTH_M
"""Vehicles longer than this are trucks: olive, with a line along their length."""
POLICY_COLOURS = {
    "level0": "tab:gray", "mutual": "tab:blue", "competitive": "tab:red", "cooperative": "tab:green",
    "sut": "orange", "nilsson": "tab:purple", "mobil": "tab:brown", "truck": "tab:olive",
}
"""Fill of a BV by its ``policy`` (driver model); the SUT is orange whatever its model."""

_F = {name: j for j, name in enumerate(C.WORLD_FIELDS)}
_FIELDS = ("x", "y", "yaw", "length", "width", "policy", "speed")
_FIELD_COLUMNS = np.array([_F[f] for f in _FIELDS])


@dataclass
class Frame:
    """One kept state: the vehicles near the SUT (``columns[f]`` ``[m]``), their ids and the SUT's row."""

    state: int
    time_s: float
    columns: dict[str, np.ndarray]
    ids: np.ndarray
    sut_row: int
    lane_change: int = 0
    """The SUT's first non-zero ``lane_change`` over the states the frame stands for (+1 left, -1 right)."""


@dataclass
class FrameSeries:
    """The frames of a run, fed a block of states at a time (module docstring)."""

    keep: int = KEEP_FRAMES
    window_m: float = WINDOW_M
    stride: int = 1
    frames: list[Frame] = field(default_factory=list)

    def add_block(self, ks: np.ndarray, times: np.ndarray, tables: np.ndarray, ids: np.ndarray, sut: int) -> None:
        """A block's states ``ks`` (``tables`` ``[n, V, F]``)."""
        # the block's states at once where it can be (docs/performance.md "Per-step work of the scores"):
        # the vehicles near the SUT in every state, the lane-change signs, the kept fields
        lc_sut = tables[:, sut, _F["lane_change"]]
        signs = [int(v) for v in np.sign(lc_sut).tolist()]
        x = tables[:, :, _F["x"]]
        near_all = np.abs(x - x[:, sut:sut + 1]) <= self.window_m + 10.0  # [n, V]
        kept = tables[:, :, _FIELD_COLUMNS]  # [n, V, len(_FIELDS)]
        time_list = times.tolist()
        for r, k in enumerate(ks.tolist()):
            if signs[r] and self.frames and self.frames[-1].state // self.stride == k // self.stride \
                    and not self.frames[-1].lane_change:
                self.frames[-1].lane_change = signs[r]
            if k % self.stride:
                continue
            near = np.flatnonzero(near_all[r])
            cols = kept[r, near].T.copy()  # [len(_FIELDS), m]: each field's values contiguous
            sut_row = int(np.searchsorted(near, sut))
            if sut_row == near.size or near[sut_row] != sut:
                raise IndexError(f"state {k}: the SUT is not near itself (x = {x[r, sut]})")
            self.frames.append(Frame(state=k, time_s=float(time_list[r]), columns=dict(zip(_FIELDS, cols)),
                                     ids=ids[near], sut_row=sut_row, lane_change=signs[r]))
            while len(self.frames) > self.keep:
                self.stride *= 2
                merged: list[Frame] = []
                for f in self.frames:
                    if merged and merged[-1].state // self.stride == f.state // self.stride:
                        merged[-1].lane_change = merged[-1].lane_change or f.lane_change
                    else:
                        merged.append(f)
                self.frames = merged


def pick(count: int, frames: int) -> list[int]:
    """Indices of ``frames`` of ``count`` kept frames, evenly spread, first and last included (all if fewer)."""
    if frames <= 0 or count == 0:
        return []
    if count <= frames:
        return list(range(count))
    if frames == 1:
        return [0]
    return sorted({int(round(i * (count - 1) / (frames - 1))) for i in range(frames)})


def _exposure_at(exposures: list[dict[str, Any]], k0: int, k1: int) -> dict[str, Any] | None:
    """The first exposure overlapping the states [k0, k1)."""
    for x in exposures:
        if x["start_state"] < k1 and x["end_state"] > k0:
            return x
    return None


_PALETTE = {"white": (255, 255, 255), "black": (0, 0, 0), "lane": (170, 170, 170), "red": (214, 39, 40),
            "orange": (255, 165, 0), "tab:gray": (127, 127, 127), "tab:blue": (31, 119, 180),
            "tab:red": (214, 39, 40), "tab:green": (44, 160, 44), "tab:purple": (148, 103, 189),
            "tab:brown": (140, 86, 75), "tab:olive": (188, 189, 34), "dark": (60, 60, 60), "involved": (230, 0, 230)}
_INDEX = {name: i for i, name in enumerate(_PALETTE)}
WIDTH_PX = 640
"""Width of the animation (px): the view of 2 x :data:`WINDOW_M` at 4 px/m."""
VIEW_HEIGHT_M = 30.0
"""Height of the view around the SUT (m)."""


@dataclass
class FrameNote:
    """What a drawn frame marks over the states it stands for, ``[state, until)``."""

    index: int
    """The frame's index in :attr:`FrameSeries.frames`."""
    state: int
    until: int
    lane_change: int
    """The SUT's first lane change in those states (+1 left, -1 right, 0 none)."""
    exposure: dict[str, Any] | None
    collision: dict[str, Any] | None


def frame_notes(series: FrameSeries, report: dict[str, Any], frames: int) -> list[FrameNote]:
    """The ``frames`` frames :func:`write_animation` draws and what each marks: the SUT's lane change,
    the first exposure (``report``'s ``safety.exposure_list``) and collision overlapping its states."""
    idx = pick(len(series.frames), frames)
    safety = report["safety"]
    out = []
    for n, i in enumerate(idx):
        stop = idx[n + 1] if n + 1 < len(idx) else len(series.frames)
        fr = series.frames[i]
        until = series.frames[stop].state if stop < len(series.frames) else series.frames[-1].state + series.stride
        change = next((f.lane_change for f in series.frames[i:stop] if f.lane_change), 0)
        hit = next((c for c in safety["collision_list"] if fr.state <= int(c["state"]) < until), None)
        out.append(FrameNote(i, fr.state, until, change, _exposure_at(safety["exposure_list"], fr.state, until), hit))
    return out


def write_animation(series: FrameSeries, lane_segments: np.ndarray | None, report: dict[str, Any], path: Path,
                    *, frames: int = ANIMATION_FRAMES, frame_ms: int = FRAME_MS, title: str | None = None
                    ) -> int:
    """Draw ``frames`` of ``series`` (evenly spread) as a GIF at ``path``; returns the frames written
    (0 and no file when there is nothing to draw). Exposures and their rules: ``report``'s
    ``safety.exposure_list``; collisions: ``safety.collision_list``.

    Drawn with Pillow directly on a fixed palette (docs/evaluation.md §7.1: matplotlib took 85 ms a
    frame, this a few ms), so a 3,000-step run's animation costs well under a second."""
    from PIL import Image, ImageDraw, ImageFont

    from evoscen_eval.scoring.exposure_rules import RULE_TEXT, involved

    notes = frame_notes(series, report, frames)
    if not notes:
        return 0
    half = series.window_m
    scale = WIDTH_PX / (2.0 * half)
    head_px, foot_px = 30, 14
    view_px = int(round(VIEW_HEIGHT_M * scale))
    height = head_px + view_px + foot_px
    palette = [v for rgb in _PALETTE.values() for v in rgb]
    font = ImageFont.load_default_imagefont()  # the bitmap font: a tenth of FreeType's time per line
    legend = ("SUT orange; BVs " + ", ".join(f"{n} {POLICY_COLOURS[n].removeprefix('tab:')}"
                                             for n in ("mutual", "competitive", "cooperative", "level0"))
              + "; trucks olive; magenta: involved")
    segs = None if lane_segments is None or not len(lane_segments) else np.asarray(lane_segments, dtype=float)
    foot = Image.new("P", (WIDTH_PX, foot_px), _INDEX["white"])
    foot.putpalette(palette)
    ImageDraw.Draw(foot).text((4, 1), legend, fill=_INDEX["dark"], font=font)
    images = []
    for note in notes:
        fr, change, x, hit = series.frames[note.index], note.lane_change, note.exposure, note.collision
        c = fr.columns
        cx, cy = float(c["x"][fr.sut_row]), float(c["y"][fr.sut_row])

        def px(x, y, cx=cx, cy=cy):  # world (m) -> image (px), y up
            return (np.asarray(x) - cx) * scale + WIDTH_PX / 2, head_px + view_px / 2 - (np.asarray(y) - cy) * scale

        im = Image.new("P", (WIDTH_PX, height), _INDEX["white"])
        im.putpalette(palette)
        draw = ImageDraw.Draw(im)
        if segs is not None:
            near = (np.abs(segs[:, :, 0] - cx).min(axis=1) < half + 20) & \
                   (np.abs(segs[:, :, 1] - cy).min(axis=1) < VIEW_HEIGHT_M)
            xs, ys = px(segs[near][:, :, 0], segs[near][:, :, 1])
            for line in np.stack([xs, ys], axis=-1).tolist():
                draw.line([tuple(p) for p in line], fill=_INDEX["lane"], width=1)
        red = set(involved(x)) if x else set()
        if hit is not None:
            red |= {int(i) for i in hit["ids"]}
        ca, sa = np.cos(c["yaw"]), np.sin(c["yaw"])
        hl, hw = c["length"] / 2, c["width"] / 2
        u, v = np.array([1, -1, -1, 1])[:, None], np.array([1, 1, -1, -1])[:, None]
        bx, by = px(c["x"] + ca * u * hl - sa * v * hw, c["y"] + sa * u * hl + ca * v * hw)  # [4, m]
        corners = np.stack([bx, by], axis=-1).transpose(1, 0, 2).tolist()  # [m, 4, 2]
        for j, vid in enumerate(fr.ids.tolist()):
            pts = [tuple(p) for p in corners[j]]
            sut = j == fr.sut_row
            truck = c["length"][j] > TRUCK_LENGTH_M
            fill = ("orange" if sut else "tab:olive" if truck
                    else POLICY_COLOURS.get(C.POLICY_NAMES.get(int(c["policy"][j]), ""), "tab:gray"))
            outlined = vid in red or (sut and (x is not None or hit is not None))
            draw.polygon(pts, fill=_INDEX[fill], outline=_INDEX["involved" if outlined else "black"],
                         width=3 if outlined else 1)
            if truck:  # a truck: a line along its length
                (a0, b0), (a1, b1) = px(c["x"][j] - ca[j] * hl[j] * 0.8, c["y"][j] - sa[j] * hl[j] * 0.8), \
                    px(c["x"][j] + ca[j] * hl[j] * 0.8, c["y"][j] + sa[j] * hl[j] * 0.8)
                draw.line([(float(a0), float(b0)), (float(a1), float(b1))], fill=_INDEX["black"], width=1)
        if change:
            yaw = float(c["yaw"][fr.sut_row]) + change * math.pi / 2
            (x0, y0), (x1, y1) = px(cx, cy), px(cx + 5.0 * math.cos(yaw), cy + 5.0 * math.sin(yaw))
            draw.line([(float(x0), float(y0)), (float(x1), float(y1))], fill=_INDEX["black"], width=2)
            draw.ellipse([float(x1) - 3, float(y1) - 3, float(x1) + 3, float(y1) + 3], fill=_INDEX["black"])
        what = []
        if change:
            what.append("SUT lane change " + ("left" if change > 0 else "right"))
        if hit is not None:
            what.append("COLLISION")
        if x is not None:
            rules = dict.fromkeys(RULE_TEXT[r["rule"]] for r in x.get("rules", []))
            what.append("EXPOSURE" + (f" ({', '.join(rules)})" if rules else ""))
        line1 = (f"{title}  " if title else "") + f"t = {fr.time_s:.1f} s, SUT {c['speed'][fr.sut_row] * 3.6:.0f} km/h"
        draw.text((4, 2), line1, fill=_INDEX["black"], font=font)
        if what:
            draw.text((4, 15), "; ".join(what), fill=_INDEX["red" if (x or hit) else "black"], font=font)
        im.paste(foot, (0, head_px + view_px))
        images.append(im)
    path = Path(path)
    images[0].save(path, save_all=True, append_images=images[1:], duration=frame_ms, loop=0)
    return len(images)
