"""A run to watch: a bird's-eye animation of the road around the SUT (``run.gif``), written beside
every report and every critical-event clip (docs/evaluation.md §7.1).

:class:`FrameSeries` keeps, block by block, one state in every ``stride`` with the vehicles within
:data:`WINDOW_M` of the SUT along x (the SUT's lane-change flag of the ``stride`` states it stands
for is kept with it); past :data:`KEEP_FRAMES` frames it drops every other and doubles the stride,
as the report's timeline does, so its memory is bounded whatever the run's length.
:func:`write_animation` draws one kept frame per ``frame_s`` seconds of driving (at most ``frames``
of them; more: evenly spread) with Pillow directly, on a fixed palette, and saves them as a GIF.

What a frame shows, :data:`WIDTH_PX` wide: a header (the time, the SUT's speed and lane change, an
exposure's rules or a collision, and a bar of the whole run with its exposures and the frame's
time); the road ±:data:`WINDOW_M` around the SUT, the view centred on it; every vehicle as its box
(its own length and width), filled by role and driver model (:data:`POLICY_COLOURS`; the SUT
orange), a truck (longer than :data:`~evoscen_contract.contract.TRUCK_MIN_LENGTH_M`) olive with a
line along its length; a pointer from the SUT towards the side it changes lanes to; during an
exposure (or a collision) the SUT and the vehicles its rules name outlined magenta; and below the
road, in a band of its own, the legend in words (:func:`legend_band`, wrapped to the width).
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
KEEP_FRAMES = 1600
"""Most frames :class:`FrameSeries` keeps (a longer run is kept at a doubled stride): at 0.1-s steps
a run of up to 12,800 states (21 min) keeps one state in 8 or more, finer than :data:`FRAME_S`."""
FRAME_S = 1.0
"""Most driving time one frame of ``run.gif`` stands for (s): at :data:`FRAME_MS` a frame, 10× real time."""
ANIMATION_FRAMES = 600
"""Most frames drawn (:func:`write_animation`'s ``frames``; ``--animation-frames``): 10 min of
driving at :data:`FRAME_S`; a longer run's frames are spread evenly over it."""
FRAME_MS = 100
"""Each frame's display time (ms): 10 frames a second."""
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


_PALETTE = {"white": (255, 255, 255), "black": (0, 0, 0), "lane": (150, 150, 150), "red": (214, 39, 40),
            "orange": (255, 165, 0), "tab:gray": (127, 127, 127), "tab:blue": (31, 119, 180),
            "tab:red": (214, 39, 40), "tab:green": (44, 160, 44), "tab:purple": (148, 103, 189),
            "tab:brown": (140, 86, 75), "tab:olive": (188, 189, 34), "dark": (60, 60, 60), "involved": (230, 0, 230),
            "bar": (225, 225, 225), "band": (245, 245, 245)}
_INDEX = {name: i for i, name in enumerate(_PALETTE)}
PX_PER_M = 8.0
"""Scale of the view (px per m)."""
WIDTH_PX = int(2 * WINDOW_M * PX_PER_M)
"""Width of the animation (px): the view of 2 x :data:`WINDOW_M` at :data:`PX_PER_M`."""
VIEW_HEIGHT_M = 30.0
"""Height of the view around the SUT (m)."""
FONT_PX = 16
"""Size of the header's and the legend's text (px)."""
HEAD_PX = 72
"""Height of the header band (two lines of text and the run bar)."""
_BAR = (8, 56, 8)
"""The run bar: left and right margin, top, height (px)."""


def _font(size: int = FONT_PX):
    from PIL import ImageFont

    return ImageFont.load_default(size=size)


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
    duration_ms: int = FRAME_MS
    """How long the frame is shown."""


def state_seconds(series: FrameSeries) -> float:
    """Seconds of driving per state of ``series`` (from its first and last kept frames; 0 with one)."""
    f = series.frames
    if len(f) < 2 or f[-1].state == f[0].state:
        return 0.0
    return (f[-1].time_s - f[0].time_s) / (f[-1].state - f[0].state)


def frame_indices(series: FrameSeries, frames: int, frame_s: float | None) -> list[int]:
    """The kept frames drawn: every ``m``-th, the largest ``m`` whose ``m`` x stride states last at
    most ``frame_s`` seconds (at least every kept frame); if that makes more than ``frames``, or
    ``frame_s`` is None, ``frames`` of them evenly spread (:func:`pick`)."""
    count = len(series.frames)
    dt = state_seconds(series)
    if frame_s is None or frames <= 0 or dt <= 0.0:
        return pick(count, frames)
    step = max(1, int(frame_s / (series.stride * dt) + 1e-9))
    idx = list(range(0, count, step))
    return idx if len(idx) <= frames else pick(count, frames)


def frame_notes(series: FrameSeries, report: dict[str, Any], frames: int, *, frame_s: float | None = None,
                centre_state: int | None = None, frame_ms: int = FRAME_MS) -> list[FrameNote]:
    """The frames :func:`write_animation` draws (:func:`frame_indices`) and what each marks: the SUT's
    lane change, the first exposure (``report``'s ``safety.exposure_list``) and collision overlapping
    its states. With ``centre_state`` the first or the last frame is held longer so that the frame
    of that state is shown in the middle of the animation (a clip cut short by the run's start or end)."""
    idx = frame_indices(series, frames, frame_s)
    safety = report["safety"]
    out = []
    for n, i in enumerate(idx):
        stop = idx[n + 1] if n + 1 < len(idx) else len(series.frames)
        fr = series.frames[i]
        until = series.frames[stop].state if stop < len(series.frames) else series.frames[-1].state + series.stride
        change = next((f.lane_change for f in series.frames[i:stop] if f.lane_change), 0)
        hit = next((c for c in safety["collision_list"] if fr.state <= int(c["state"]) < until), None)
        out.append(FrameNote(i, fr.state, until, change, _exposure_at(safety["exposure_list"], fr.state, until), hit,
                             frame_ms))
    if centre_state is not None and out:
        e = next((n for n, note in enumerate(out) if note.state <= centre_state < note.until), len(out) - 1)
        before = sum(note.duration_ms for note in out[:e])
        after = sum(note.duration_ms for note in out[e + 1:])
        (out[0] if before < after else out[-1]).duration_ms += abs(after - before)
    return out


@dataclass
class Legend:
    """The legend band (:func:`legend_band`): its image and the box of every text in it (band px)."""

    image: Any
    text_boxes: list[tuple[int, int, int, int]]


def legend_items(frame_s: float | None, frame_ms: int = FRAME_MS, clip: bool = False) -> list[tuple[str, str]]:
    """The legend's entries ``(mark, words)``; a mark is a fill colour, ``truck``, ``involved``,
    ``pointer``, ``bar``, ``""`` (words alone) or ``newline`` (the next entry starts a row); ``clip``:
    the top bar spans a clip, its event marked."""
    speed = ""
    if frame_s:
        times = frame_s / (frame_ms / 1000.0)
        speed = "real time" if abs(times - 1.0) < 1e-9 else f"{times:g} times real time"
    return [("orange", "SUT (the system under test), always in the middle of the view"),
            ("involved", "outlined: in an exposure (a safety rule broken) or a collision"),
            ("pointer", "the SUT changing lanes"), ("newline", ""),
            ("", "Other vehicles by driver model:"),
            *((POLICY_COLOURS[n], w) for n, w in (("mutual", "mutual"), ("competitive", "competitive"),
                                                   ("cooperative", "cooperative"), ("level0", "level-0"),
                                                   ("nilsson", "Nilsson"), ("mobil", "MOBIL"))),
            ("truck", f"truck (longer than {TRUCK_LENGTH_M:g} m)"), ("newline", ""),
            ("bar", ("top bar: the clip, the triangle its event" if clip else "top bar: the whole run")
             + "; exposures magenta, collisions red, challenges blue, now black"),
            ("", f"View: {2 * WINDOW_M:g} m of road around the SUT."
                 + (f" Each frame {frame_s:g} s of driving, played at {speed}." if speed else ""))]


def legend_band(width: int, frame_s: float | None = FRAME_S, frame_ms: int = FRAME_MS, clip: bool = False) -> Legend:
    """The legend drawn in a band ``width`` px wide, its entries wrapped into as many rows as they need."""
    from PIL import Image, ImageDraw

    font = _font()
    measure = ImageDraw.Draw(Image.new("P", (1, 1)))
    pad, gap, mark_w, row_h = 8, 18, 26, FONT_PX + 10
    placed, x, row = [], pad, 0
    for mark, words in legend_items(frame_s, frame_ms, clip):
        if mark == "newline":
            x = width  # the next entry starts a row
            continue
        lead = mark_w + 6 if mark else 0
        pieces = [words]
        if lead + measure.textlength(words, font=font) > width - 2 * pad:  # longer than a row: wrapped at spaces
            pieces = [""]
            for word in words.split(" "):
                line = f"{pieces[-1]} {word}".strip()
                first = len(pieces) == 1
                if pieces[-1] and (lead if first else 0) + measure.textlength(line, font=font) > width - 2 * pad:
                    pieces.append(word)
                else:
                    pieces[-1] = line
        for n, piece in enumerate(pieces):
            w = (lead if n == 0 else 0) + int(math.ceil(measure.textlength(piece, font=font)))
            if x > pad and (n > 0 or x + w > width - pad):
                x, row = pad, row + 1
            placed.append((x, row, mark if n == 0 else "", piece))
            x += w + gap
    im = Image.new("P", (width, pad * 2 + row_h * (row + 1)), _INDEX["band"])
    im.putpalette([v for rgb in _PALETTE.values() for v in rgb])
    draw = ImageDraw.Draw(im)
    boxes = []
    for x, row, mark, words in placed:
        y = pad + row * row_h
        mid = y + row_h // 2
        if mark:
            box = [x, mid - 6, x + mark_w, mid + 6]
            if mark == "involved":
                draw.rectangle(box, fill=_INDEX["white"], outline=_INDEX["involved"], width=3)
            elif mark == "pointer":
                draw.line([(x + 2, mid), (x + mark_w - 6, mid)], fill=_INDEX["black"], width=2)
                draw.ellipse([x + mark_w - 9, mid - 3, x + mark_w - 3, mid + 3], fill=_INDEX["black"])
            elif mark == "bar":
                draw.rectangle([x, mid - 4, x + mark_w, mid + 4], fill=_INDEX["bar"])
                draw.rectangle([x + 6, mid - 4, x + 12, mid + 4], fill=_INDEX["involved"])
                draw.rectangle([x + 18, mid - 6, x + 19, mid + 6], fill=_INDEX["black"])
            else:
                draw.rectangle(box, fill=_INDEX["tab:olive" if mark == "truck" else mark], outline=_INDEX["black"])
                if mark == "truck":
                    draw.line([(x + 4, mid), (x + mark_w - 4, mid)], fill=_INDEX["black"], width=1)
            x += mark_w + 6
        draw.text((x, mid), words, fill=_INDEX["black"], font=font, anchor="lm")
        boxes.append(tuple(int(v) for v in draw.textbbox((x, mid), words, font=font, anchor="lm")))
    return Legend(im, boxes)


def _run_bar(draw, notes: list[FrameNote], report: dict[str, Any], series: FrameSeries, width: int):
    """The bar of the whole run (its exposures magenta, collisions red) and a function giving a
    state's x on it."""
    left, top, h = _BAR
    k0, k1 = series.frames[0].state, series.frames[-1].state + series.stride
    span = max(1, k1 - k0)

    def at(k: float) -> float:
        return left + (min(max(k, k0), k1) - k0) / span * (width - 2 * left)

    draw.rectangle([left, top, width - left, top + h], fill=_INDEX["bar"])
    for x in report["safety"]["exposure_list"]:
        a, b = at(x["start_state"]), at(x["end_state"])
        draw.rectangle([a, top, max(b, a + 2), top + h], fill=_INDEX["involved"])
    for c in report["safety"]["collision_list"]:
        a = at(int(c["state"]))
        draw.rectangle([a - 1, top, a + 2, top + h], fill=_INDEX["red"])
    for o in (report.get("challenge") or {}).get("onsets", ()):  # the SUT's leader starts braking hard
        a = at(int(o["step"]))
        draw.rectangle([a - 1, top, a + 2, top + h // 2], fill=_INDEX["tab:blue"])
    return at


def _line_directions(segs: np.ndarray | None) -> tuple[np.ndarray, np.ndarray] | None:
    """Each lane-line piece's midpoint ``[N, 2]`` and direction (rad, either way along it: in [-pi/2, pi/2))."""
    if segs is None:
        return None
    d = segs[:, 1] - segs[:, 0]
    return segs[:, :2].mean(axis=1), (np.arctan2(d[:, 1], d[:, 0]) + math.pi / 2) % math.pi - math.pi / 2


def _road_heading(lines: tuple[np.ndarray, np.ndarray] | None, cx: float, cy: float) -> tuple[float, float]:
    """Cosine and sine of the road's heading at ``(cx, cy)``: the median direction of the lane-line
    pieces within 30 m (the view turns with the road; (1, 0) without lane lines near)."""
    if lines is None:
        return 1.0, 0.0
    mid, direction = lines
    near = np.hypot(mid[:, 0] - cx, mid[:, 1] - cy) < 30.0
    if not near.any():
        return 1.0, 0.0
    a = float(np.median(direction[near]))
    return math.cos(a), math.sin(a)


def write_animation(series: FrameSeries, lane_segments: np.ndarray | None, report: dict[str, Any], path: Path,
                    *, frames: int = ANIMATION_FRAMES, frame_ms: int = FRAME_MS, frame_s: float | None = FRAME_S,
                    centre_state: int | None = None, title: str | None = None) -> int:
    """Draw the frames of :func:`frame_notes` (one per ``frame_s`` s of driving, at most ``frames``;
    ``centre_state``: shown mid-animation) as a GIF at ``path``; returns the frames written (0 and no
    file when there is nothing to draw). Exposures and their rules: ``report``'s
    ``safety.exposure_list``; collisions: ``safety.collision_list``.

    Drawn with Pillow directly on a fixed palette (docs/evaluation.md §7.1: matplotlib took 85 ms a
    frame, this a few ms)."""
    from PIL import Image, ImageDraw

    from evoscen_eval.scoring.exposure_rules import RULE_TEXT, involved

    notes = frame_notes(series, report, frames, frame_s=frame_s, centre_state=centre_state, frame_ms=frame_ms)
    if not notes:
        return 0
    half, width = series.window_m, WIDTH_PX
    scale = width / (2.0 * half)
    view_px = int(round(VIEW_HEIGHT_M * scale))
    dt = state_seconds(series)
    legend = legend_band(width, frame_s if frame_s and dt else None, frame_ms, clip=centre_state is not None)
    height = HEAD_PX + view_px + legend.image.height
    palette = [v for rgb in _PALETTE.values() for v in rgb]
    font = _font()
    segs = None if lane_segments is None or not len(lane_segments) else np.asarray(lane_segments, dtype=float)
    lines = _line_directions(segs)
    base = Image.new("P", (width, height), _INDEX["white"])
    base.putpalette(palette)
    at = _run_bar(ImageDraw.Draw(base), notes, report, series, width)
    base.paste(legend.image, (0, HEAD_PX + view_px))
    draw = ImageDraw.Draw(base)
    draw.line([(0, HEAD_PX - 1), (width, HEAD_PX - 1)], fill=_INDEX["lane"])
    if centre_state is not None:  # the event's place on the bar
        draw.polygon([(at(centre_state) - 6, HEAD_PX - 8), (at(centre_state) + 6, HEAD_PX - 8),
                      (at(centre_state), HEAD_PX - 2)], fill=_INDEX["involved"])
    images = []
    for note in notes:
        fr, change, x, hit = series.frames[note.index], note.lane_change, note.exposure, note.collision
        c = fr.columns
        cx, cy = float(c["x"][fr.sut_row]), float(c["y"][fr.sut_row])
        ct, st = _road_heading(lines, cx, cy)

        def px(x, y, cx=cx, cy=cy, ct=ct, st=st):  # world (m) -> image (px), y up, the road along x
            dx, dy = np.asarray(x) - cx, np.asarray(y) - cy
            return (dx * ct + dy * st) * scale + width / 2, view_px / 2 - (dy * ct - dx * st) * scale

        view = Image.new("P", (width, view_px), _INDEX["white"])  # the road, clipped to its band
        view.putpalette(palette)
        draw = ImageDraw.Draw(view)
        if segs is not None:
            near = np.hypot(segs[:, :, 0] - cx, segs[:, :, 1] - cy).min(axis=1) < half + 20
            xs, ys = px(segs[near][:, :, 0], segs[near][:, :, 1])
            for line in np.stack([xs, ys], axis=-1).tolist():
                draw.line([tuple(p) for p in line], fill=_INDEX["lane"], width=2)
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
                         width=4 if outlined else 1)
            if truck:  # a truck: a line along its length
                (a0, b0), (a1, b1) = px(c["x"][j] - ca[j] * hl[j] * 0.8, c["y"][j] - sa[j] * hl[j] * 0.8), \
                    px(c["x"][j] + ca[j] * hl[j] * 0.8, c["y"][j] + sa[j] * hl[j] * 0.8)
                draw.line([(float(a0), float(b0)), (float(a1), float(b1))], fill=_INDEX["black"], width=2)
        if change:
            yaw = float(c["yaw"][fr.sut_row]) + change * math.pi / 2
            (x0, y0), (x1, y1) = px(cx, cy), px(cx + 4.0 * math.cos(yaw), cy + 4.0 * math.sin(yaw))
            draw.line([(float(x0), float(y0)), (float(x1), float(y1))], fill=_INDEX["black"], width=3)
            draw.ellipse([float(x1) - 5, float(y1) - 5, float(x1) + 5, float(y1) + 5], fill=_INDEX["black"])
        im = base.copy()
        im.paste(view, (0, HEAD_PX))
        draw = ImageDraw.Draw(im)
        line1 = (f"{title}    " if title else "") + f"t = {fr.time_s:.1f} s    SUT {c['speed'][fr.sut_row] * 3.6:.0f} km/h"
        if change:
            line1 += "    SUT changing lanes to the " + ("left" if change > 0 else "right")
        draw.text((8, 4), line1, fill=_INDEX["black"], font=font)
        what = []
        if hit is not None:
            what.append("COLLISION of the SUT (outlined)")
        if x is not None:
            rules = dict.fromkeys(RULE_TEXT[r["rule"]] for r in x.get("rules", []))
            what.append("EXPOSURE" + (f": {', '.join(rules)}" if rules else "") + " (the vehicles outlined)")
        if what:
            draw.text((8, 28), "; ".join(what), fill=_INDEX["red" if hit else "involved"], font=font)
        k = at(fr.state)
        top, h = _BAR[1], _BAR[2]
        draw.rectangle([k - 1, top - 3, k + 2, top + h + 3], fill=_INDEX["black"])
        images.append(im)
    path = Path(path)
    images[0].save(path, save_all=True, append_images=images[1:], duration=[n.duration_ms for n in notes], loop=0)
    return len(images)
