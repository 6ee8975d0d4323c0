"""An exported OpenSCENARIO file read back, and its collisions checked independently (docs/export.md).

:func:`read_xosc_tracks` reads the entities and their timed polylines with nothing but ``xml``;
:func:`box_collisions` finds the collisions on those trajectories with shapely (oriented boxes), so the
check shares no code with evoscen's collision kernel; :func:`compare_collisions` sets them against the
range's collision events. The export itself: :mod:`evoscen_eval.scenes.scenario_export`.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

EPS_T = 1e-6
"""Times closer than this are the same time (s)."""


@dataclass
class XoscTrack:
    """One entity of an OpenSCENARIO file as :func:`read_xosc_tracks` reads it."""

    name: str
    category: str
    length_m: float
    width_m: float
    properties: dict[str, str]
    init_pose: tuple[float, float, float]
    init_speed: float
    samples: list[tuple[float, float, float, float]]
    """(time, x, y, heading) of every polyline vertex of its FollowTrajectoryActions, by time, and its
    Init pose at time 0 when no vertex is there."""


def read_xosc_tracks(path: Path | str) -> dict[str, XoscTrack]:
    """The entities of an OpenSCENARIO file: size, category, properties, Init pose and speed, and the
    vertices of their timed polylines (plain ``xml``, no evoscen code)."""
    root = ET.parse(path).getroot()
    out: dict[str, XoscTrack] = {}
    for obj in root.iter("ScenarioObject"):
        veh = obj.find("Vehicle")
        dims = veh.find("BoundingBox/Dimensions")
        props = {p.get("name"): p.get("value") for p in veh.iter("Property")}
        out[obj.get("name")] = XoscTrack(obj.get("name"), veh.get("vehicleCategory"), float(dims.get("length")),
                                         float(dims.get("width")), props, (0.0, 0.0, 0.0), 0.0, [])
    placed = set()
    for private in root.iter("Private"):
        tr = out[private.get("entityRef")]
        for wp in private.iter("WorldPosition"):
            placed.add(tr.name)
            tr.init_pose = (float(wp.get("x")), float(wp.get("y")), float(wp.get("h")))
        for sa in private.iter("AbsoluteTargetSpeed"):
            tr.init_speed = float(sa.get("value"))
    for mg in root.iter("ManeuverGroup"):
        actor = mg.find("Actors/EntityRef").get("entityRef")
        for vertex in mg.iter("Vertex"):
            wp = vertex.find("Position/WorldPosition")
            out[actor].samples.append((float(vertex.get("time")), float(wp.get("x")), float(wp.get("y")),
                                       float(wp.get("h"))))
    for tr in out.values():
        # the Init pose is the state at time 0; a first piece of a single state has no vertex there
        if tr.name in placed and not any(abs(t) < EPS_T for t, *_ in tr.samples):
            tr.samples.append((0.0, *tr.init_pose))
        tr.samples.sort()
    return out


def box_collisions(tracks: dict[str, XoscTrack], dt_s: float) -> list[tuple[float, tuple[str, str]]]:
    """Collisions on the exported trajectories: the times (on the file's clock) at which two
    entities' oriented boxes begin to overlap (an intersection of positive area; the state before did
    not overlap), with the entity names sorted. Shapely polygons, sampled at the vertices' times."""
    from shapely.geometry import Polygon

    times = sorted({round(t / dt_s) for tr in tracks.values() for t, *_ in tr.samples})
    at: dict[str, dict[int, tuple[float, float, float]]] = {
        name: {round(t / dt_s): (x, y, h) for t, x, y, h in tr.samples} for name, tr in tracks.items()}
    names = sorted(tracks)

    def box(name: str, pose: tuple[float, float, float]) -> Polygon:
        tr = tracks[name]
        x, y, h = pose
        c, s = math.cos(h), math.sin(h)
        hl, hw = 0.5 * tr.length_m, 0.5 * tr.width_m
        return Polygon([(x + c * a - s * b, y + s * a + c * b) for a, b in ((hl, hw), (-hl, hw), (-hl, -hw), (hl, -hw))])

    contacts: set[tuple[str, str]] = set()
    out = []
    for n, k in enumerate(times):
        present = [(name, at[name][k]) for name in names if k in at[name]]
        now = set()
        for i in range(len(present)):
            a, pa = present[i]
            ra = 0.5 * math.hypot(tracks[a].length_m, tracks[a].width_m)
            for j in range(i + 1, len(present)):
                b, pb = present[j]
                rb = 0.5 * math.hypot(tracks[b].length_m, tracks[b].width_m)
                if math.hypot(pa[0] - pb[0], pa[1] - pb[1]) >= ra + rb:
                    continue
                if box(a, pa).intersection(box(b, pb)).area > 1e-9:
                    now.add((a, b))
        if n:
            out.extend((k * dt_s, pair) for pair in sorted(now - contacts))
        contacts = now
    return out


COLLISION_TIME_TOLERANCE_S = 0.1
"""How far apart in time evoscen's collision event and the independent check's may be (s)."""


def compare_collisions(ex, xosc_path: Path | str) -> tuple[bool, list[str]]:
    """evoscen's collision events of the range ``ex`` (:class:`evoscen_eval.scenes.scenario_export.RangeExport`)
    against :func:`box_collisions` on the exported file:
    ``(agree, lines)``; they agree when both find the same pairs (by vehicle id) and each pair's times
    differ by at most :data:`COLLISION_TIME_TOLERANCE_S`."""
    tracks = read_xosc_tracks(xosc_path)
    ids = {name: int(tr.properties["evoscen:id"]) for name, tr in tracks.items()}
    found = [(round(ex.t_from_s + t, 9), tuple(sorted((ids[a], ids[b])))) for t, (a, b) in box_collisions(tracks, ex.dt_s)]
    ours = list(ex.collisions)
    unmatched = list(found)
    lines, agree = [], True
    for t, pair in ours:
        match = next((f for f in unmatched if f[1] == pair and abs(f[0] - t) <= COLLISION_TIME_TOLERANCE_S + EPS_T), None)
        if match is None:
            agree = False
            lines.append(f"  evoscen collision {pair[0]}-{pair[1]} at t = {t:.2f} s: not found by the box check")
        else:
            unmatched.remove(match)
            lines.append(f"  collision {pair[0]}-{pair[1]}: evoscen t = {t:.2f} s, box check t = {match[0]:.2f} s")
    for t, pair in unmatched:
        agree = False
        lines.append(f"  box check collision {pair[0]}-{pair[1]} at t = {t:.2f} s: no evoscen collision event")
    head = (f"independent collision check (shapely boxes): {len(found)} collision(s), evoscen: {len(ours)}; "
            + ("agree" if agree else "DISAGREE"))
    return agree, [head, *lines]
