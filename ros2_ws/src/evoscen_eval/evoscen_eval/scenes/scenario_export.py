"""A recorded run's time range as an OpenSCENARIO or CommonRoad scenario (docs/export.md).

:func:`load_range` cuts a bag (a whole run or a critical-event clip) to ``[t_from, t_to]`` and splits
every vehicle's motion into *pieces*: runs of states without a jump. A vehicle jumps when the
traffic window moves every vehicle back (``evoscen/shift``) or when it re-enters as a new trip
(``evoscen/re-entry``); a step moving a vehicle further than it can drive is a jump
(:data:`JUMP_SLACK_M`, docs/export.md "Pieces"). :func:`write_xosc` writes the range as OpenSCENARIO
1.2 (scenariogeneration), :func:`write_commonroad` as a CommonRoad 2020a XML file (commonroad-io).
:func:`read_xosc_tracks` reads an exported OpenSCENARIO file back with nothing but ``xml``, and
:func:`box_collisions` (both in :mod:`evoscen_eval.scenes.xosc_readback`, served here too) finds the collisions
on those trajectories with shapely (oriented boxes), so
the check shares no code with evoscen's collision kernel. :func:`initial_state_from_xosc` turns an
exported file's ``Init`` back into an evoscen start (``run_scenario.py --start-from``).

The world table carries each vehicle's map-frame pose (``x``, ``y``, ``yaw``: the road model's
``frenet_to_cartesian`` of ``s``, ``d`` plus the heading relative to the road), which is the
OpenDRIVE inertial frame of the shipped map, so the export uses those columns as they are.
"""

from __future__ import annotations

import math
import shutil
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from evoscen_contract import contract as C
from evoscen_contract.contract import TRUCK_MIN_LENGTH_M  # longer: exported as a truck (docs/export.md)
from evoscen_sim.errors import InputError

from evoscen_eval.scenes.event_ranges import shifts_of
from evoscen_eval.scenes.export_vehicles import limits_of, policy_code, truck_driven, xosc_vehicle
from evoscen_eval.scenes.xosc_readback import (  # noqa: F401  (the read-back's names, served here too)
    COLLISION_TIME_TOLERANCE_S, EPS_T, XoscTrack, box_collisions, compare_collisions, read_xosc_tracks)

JUMP_SLACK_M = 5.0
"""A step that moves a vehicle further than ``speed * dt + JUMP_SLACK_M`` (its larger speed of the
two states) is a jump: a new piece begins (docs/export.md "Pieces")."""
VEHICLE_HEIGHT_M = {"car": 1.5, "truck": 3.5}
"""Heights written in the OpenSCENARIO bounding boxes (evoscen's vehicles are 2-D)."""
FORMATS = ("xosc", "commonroad")
SUT_NAME = "sut"
SUT_CONTROLLER = "sut_controller"


def vehicle_class(length_m: float, truck_min_length_m: float = TRUCK_MIN_LENGTH_M) -> str:
    """``"truck"`` for a vehicle longer than ``truck_min_length_m``, else ``"car"``."""
    return "truck" if length_m > truck_min_length_m else "car"


def entity_name(vid: int, role: int) -> str:
    """The OpenSCENARIO entity name of vehicle ``vid``: ``sut`` or ``bv<id>``."""
    return SUT_NAME if role == C.ROLE_SUT else f"bv{vid}"


@dataclass
class Piece:
    """One vehicle's states ``k0 .. k0 + len - 1`` of the range (indices from the range's start)."""

    k0: int
    x: np.ndarray
    y: np.ndarray
    yaw: np.ndarray
    speed: np.ndarray
    accel: np.ndarray

    @property
    def steps(self) -> int:
        return int(self.x.shape[0])


@dataclass
class Track:
    """One vehicle of the range: who it is, its size and its pieces."""

    vid: int
    role: int
    policy: int
    length_m: float
    width_m: float
    klass: str
    lane0: int
    s0: float
    d0: float
    pieces: list[Piece] = field(default_factory=list)

    @property
    def name(self) -> str:
        return entity_name(self.vid, self.role)


@dataclass
class RangeExport:
    """A bag's time range, ready to be written (see the module docstring)."""

    bag: Path
    t_from_s: float
    """Run time of the range's first state (the exported scenarios start at 0 there)."""
    dt_s: float
    states: int
    tracks: list[Track]
    collisions: list[tuple[float, tuple[int, int]]]
    """evoscen's collision events in ``(t_from, t_to]``: (run time, sorted id pair)."""
    map_path: Path
    scenario: dict | None
    shifts: list[tuple[float, float]] = field(default_factory=list)
    """The traffic window's shifts of the whole bag: (time of the state each led to, metres moved back)."""
    warnings: list[str] = field(default_factory=list)
    """The bag reader's warnings (a truncated or corrupt bag: the readable prefix was read)."""

    @property
    def duration_s(self) -> float:
        return (self.states - 1) * self.dt_s

    @property
    def sut(self) -> Track:
        return next(t for t in self.tracks if t.role == C.ROLE_SUT)


def _split(x: np.ndarray, y: np.ndarray, v: np.ndarray, dt: float, events: set[int]) -> list[int]:
    """Indices where a new piece begins (0 first): the states a re-entry or a shift led to (``events``)
    and every step longer than the vehicle can drive."""
    starts = {0} | {k for k in events if 0 < k < x.shape[0]}
    if x.shape[0] >= 2:
        step = np.hypot(np.diff(x), np.diff(y))
        reach = np.maximum(np.abs(v[1:]), np.abs(v[:-1])) * dt + JUMP_SLACK_M
        starts.update(int(k) + 1 for k in np.flatnonzero(step > reach))
    return sorted(starts)


def load_range(bag: Path | str, t_from_s: float | None = None, t_to_s: float | None = None, *,
               truck_min_length_m: float = TRUCK_MIN_LENGTH_M) -> RangeExport:
    """The states of ``bag`` with run time in ``[t_from_s, t_to_s]`` (default: all of it).

    Raises:
        InputError: unreadable bag, a range outside the bag's states or holding fewer than two states.
    """
    from evoscen_sim.config.scenario_config import share_path

    from evoscen_eval.scoring.rundata import read_run

    run = read_run(bag)
    t = np.asarray(run.time_s, dtype=float)
    first, last = float(t[0]), float(t[-1])
    lo = first if t_from_s is None else float(t_from_s)
    hi = last if t_to_s is None else float(t_to_s)
    if not (math.isfinite(lo) and first - EPS_T <= lo <= last + EPS_T):
        raise InputError(f"--from: {lo:g} s: expected a time within the bag's states, {first:g} .. {last:g} s")
    if not (math.isfinite(hi) and first - EPS_T <= hi <= last + EPS_T):
        raise InputError(f"--to: {hi:g} s: expected a time within the bag's states, {first:g} .. {last:g} s")
    k_from = int(np.searchsorted(t, lo - EPS_T))
    k_to = int(np.searchsorted(t, hi + EPS_T)) - 1
    if k_to - k_from < 1:
        raise InputError(f"--from/--to: {lo:g} .. {hi:g} s holds {max(0, k_to - k_from + 1)} world state(s); "
                         "expected a range of at least two states (one step)")
    cols = {f: run.columns[f][k_from:k_to + 1] for f in ("x", "y", "yaw", "speed", "accel", "role", "policy",
                                                          "length", "width", "lane", "s", "d")}
    dt = float(run.dt_s)
    # the state each re-entry / shift led to (its event carries that state's time), from the range's start
    jumps: dict[int, set[int]] = {int(vid): set() for vid in run.ids.tolist()}
    for e in run.events:
        if e["name"] in (C.EVENT_REENTRY, C.EVENT_SHIFT):
            k = int(np.searchsorted(t, float(e["time_s"]) - EPS_T)) - k_from
            for vid in (e.get("ids") or []) if e["name"] == C.EVENT_REENTRY else list(jumps):
                jumps.setdefault(int(vid), set()).add(k)
    tracks = []
    for v, vid in enumerate(run.ids.tolist()):
        x, y, yaw = cols["x"][:, v], cols["y"][:, v], cols["yaw"][:, v]
        speed, accel = cols["speed"][:, v], cols["accel"][:, v]
        length, width = float(cols["length"][0, v]), float(cols["width"][0, v])
        starts = _split(x, y, speed, dt, jumps[int(vid)])
        pieces = [Piece(a, x[a:b].copy(), y[a:b].copy(), np.unwrap(yaw[a:b]), speed[a:b].copy(), accel[a:b].copy())
                  for a, b in zip(starts, [*starts[1:], x.shape[0]])]
        tracks.append(Track(int(vid), int(cols["role"][0, v]), int(cols["policy"][0, v]), length, width,
                            vehicle_class(length, truck_min_length_m), int(cols["lane"][0, v]),
                            float(cols["s"][0, v]), float(cols["d"][0, v]), pieces))
    t_lo, t_hi = float(t[k_from]), float(t[k_to])
    collisions = sorted((float(e["time_s"]), tuple(sorted(int(i) for i in e["ids"])))
                        for e in run.events_named(C.EVENT_COLLISION)
                        if t_lo + EPS_T < float(e["time_s"]) <= t_hi + EPS_T)
    map_name = (run.scenario or {}).get("map", "onramp.xodr")
    map_path = Path(map_name)
    if not map_path.is_file():
        try:
            map_path = share_path(f"maps/{map_path.name}")
        except Exception:  # noqa: BLE001 - any failure to find it is the one line below
            map_path = None
        if map_path is None or not Path(map_path).is_file():
            raise InputError(f"bag {str(bag)!r}: map {map_name!r}: not found (expected a shipped map of "
                             "evoscen_sim's maps/ or an existing file)")
    return RangeExport(Path(bag), t_lo, dt, k_to - k_from + 1, tracks, collisions, Path(map_path), run.scenario,
                       shifts_of(run), list(run.warnings))


# ---------------------------------------------------------------------------------------------- OpenSCENARIO


def _world(x: float, y: float, h: float):
    from scenariogeneration import xosc

    return xosc.WorldPosition(x=float(x), y=float(y), z=0.0, h=float(h))


def write_xosc(ex: RangeExport, out_dir: Path | str, name: str = "scenario") -> Path:
    """``out_dir/<name>.xosc`` (OpenSCENARIO 1.2) with the map copied beside it; returns the file.

    Every vehicle is an entity (``sut``, ``bv<id>``) of category car or truck with its bounding box
    centred on its reference point (evoscen's ``x``, ``y`` are the box centre) and the run's limits
    (:func:`~evoscen_eval.scenes.export_vehicles.xosc_vehicle`); ``Init`` places it and
    sets its speed; each piece of its motion is one event at the piece's start time: a teleport to
    the piece's first pose (pieces after the first), then a FollowTrajectoryAction along a timed
    polyline of the recorded poses (absolute timing, following mode ``position``). The SUT's events
    are in a story of their own (``sut_recorded``) and the SUT has a controller ``sut_controller``
    (docs/export.md "Replacing the SUT").
    """
    from scenariogeneration import xosc

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    road_file = out_dir / ex.map_path.name
    shutil.copyfile(ex.map_path, road_file)
    road = xosc.RoadNetwork(roadfile=road_file.name)
    entities = xosc.Entities()
    init = xosc.Init()
    bv_story_act = xosc.Act("bvs_recorded", xosc.ValueTrigger("start", 0, xosc.ConditionEdge.none,
                                                               xosc.SimulationTimeCondition(0, xosc.Rule.greaterOrEqual)))
    sut_act = xosc.Act("sut_recorded", xosc.ValueTrigger("start", 0, xosc.ConditionEdge.none,
                                                          xosc.SimulationTimeCondition(0, xosc.Rule.greaterOrEqual)))
    limits = limits_of(ex.scenario)
    for tr in ex.tracks:
        veh = xosc_vehicle(tr, limits["truck" if truck_driven(tr, ex.scenario) else "car"], VEHICLE_HEIGHT_M[tr.klass])
        if tr.role == C.ROLE_SUT:
            props = xosc.Properties()
            props.add_property("evoscen:default", "the recorded trajectory (story sut_recorded)")
            entities.add_scenario_object(tr.name, veh, xosc.Controller(SUT_CONTROLLER, props))
        else:
            entities.add_scenario_object(tr.name, veh)
        p0 = tr.pieces[0]
        init.add_init_action(tr.name, xosc.TeleportAction(_world(p0.x[0], p0.y[0], p0.yaw[0])))
        init.add_init_action(tr.name, xosc.AbsoluteSpeedAction(
            float(p0.speed[0]), xosc.TransitionDynamics(xosc.DynamicsShapes.step, xosc.DynamicsDimension.time, 0)))
        man = xosc.Maneuver(f"{tr.name}_motion")
        for n, p in enumerate(tr.pieces):
            if n == 0 and p.steps < 2:
                # a first piece of one state (a jump right after the range's first state): Init places
                # the vehicle there, and an event without an action is invalid (docs/export.md "Pieces")
                continue
            t0 = p.k0 * ex.dt_s
            ev = xosc.Event(f"{tr.name}_piece{n}", xosc.Priority.parallel)
            ev.add_trigger(xosc.ValueTrigger(f"{tr.name}_piece{n}_start", 0, xosc.ConditionEdge.none,
                                             xosc.SimulationTimeCondition(max(t0 - 0.5 * ex.dt_s, 0.0)
                                                                          if n else 0, xosc.Rule.greaterOrEqual)))
            if n:
                ev.add_action(f"{tr.name}_teleport{n}", xosc.TeleportAction(_world(p.x[0], p.y[0], p.yaw[0])))
            if p.steps >= 2:
                times = [round(t0 + i * ex.dt_s, 9) for i in range(p.steps)]
                poly = xosc.Polyline(times, [_world(*pose) for pose in zip(p.x, p.y, p.yaw)])
                traj = xosc.Trajectory(f"{tr.name}_trajectory{n}", False)
                traj.add_shape(poly)
                ev.add_action(f"{tr.name}_follow{n}", xosc.FollowTrajectoryAction(
                    traj, xosc.FollowingMode.position, xosc.ReferenceContext.absolute, 1, 0))
            man.add_event(ev)
        mg = xosc.ManeuverGroup(f"{tr.name}_group")
        mg.add_actor(tr.name)
        mg.add_maneuver(man)
        (sut_act if tr.role == C.ROLE_SUT else bv_story_act).add_maneuver_group(mg)
    stop = xosc.ValueTrigger("end", 0, xosc.ConditionEdge.rising,
                             xosc.SimulationTimeCondition(round(ex.duration_s, 9), xosc.Rule.greaterThan), "stop")
    sb = xosc.StoryBoard(init, stop)
    bv_story = xosc.Story("bvs_recorded")
    bv_story.add_act(bv_story_act)
    sut_story = xosc.Story("sut_recorded")
    sut_story.add_act(sut_act)
    sb.add_story(sut_story)
    if bv_story_act.maneuvergroup:
        sb.add_story(bv_story)
    sc = xosc.Scenario(f"evoscen {ex.bag.name} {ex.t_from_s:.1f}-{ex.t_from_s + ex.duration_s:.1f} s", "evoscen",
                       xosc.ParameterDeclarations(), entities, sb, road, xosc.Catalog(), osc_minor_version=2)
    path = out_dir / f"{name}.xosc"
    sc.write_xml(str(path), prettyprint=True)
    return path


def check_xosc(path: Path | str) -> list[str]:
    """The ASAM Quality Checker's (``asam-qc-openscenarioxml``, run as ``python -m qc_openscenario``
    in a process of its own: it configures the root logger) issues of level error in ``path``, one
    line each (empty: the file passes); RuntimeError if the checker did not run to its end."""
    import subprocess
    import sys
    import tempfile

    from qc_baselib import Configuration, Result
    from qc_baselib.models.common import IssueSeverity

    with tempfile.TemporaryDirectory() as tmp:
        cfg = Configuration()
        cfg.set_config_param("InputFile", str(Path(path).resolve()))
        cfg.register_checker_bundle("xoscBundle")
        result_file = Path(tmp) / "xosc.xqar"
        cfg.set_checker_bundle_param("xoscBundle", "resultFile", str(result_file))
        cfg_file = Path(tmp) / "config.xml"
        cfg.write_to_file(str(cfg_file))
        proc = subprocess.run([sys.executable, "-m", "qc_openscenario", "-c", str(cfg_file)], capture_output=True,
                              text=True, check=False, cwd=tmp)
        if proc.returncode != 0 or not result_file.is_file():
            raise RuntimeError(f"qc_openscenario ended with status {proc.returncode}: {proc.stderr.strip()[-500:]}")
        result = Result()
        result.load_from_file(str(result_file))
        out = []
        for bundle in result.get_checker_bundle_results():
            for checker in bundle.checkers:
                for issue in checker.issues:
                    if issue.level == IssueSeverity.ERROR:
                        out.append(f"{checker.checker_id}: {issue.description}")
        return out


# ---------------------------------------------------------------------------------------------- CommonRoad

LANELET_STEP_M = 2.0
"""Sampling of the lanelets' borders along the reference line (m): on the shipped map's arc (R = 2000 m)
a chord of 2 m leaves the arc by 0.25 mm."""


def lanelet_network(road):
    """The road's lanes as CommonRoad lanelets: one per lane and stretch between the s where any
    lane begins or ends, borders from the road model's lane borders, with predecessors,
    successors and same-direction neighbours. Returns (LaneletNetwork, {(lane, stretch): id})."""
    protobuf_runtime()
    from commonroad.common.common_lanelet import LaneletType
    from commonroad.scenario.lanelet import Lanelet, LaneletNetwork

    cuts = {0.0, float(road.length_m)}
    for k in range(road.num_lanes):
        for s in (float(road.lane_start_s[k]), float(road.lane_end_s[k])):
            if 0.0 < s < road.length_m:
                cuts.add(s)
    cuts = sorted(cuts)
    ids: dict[tuple[int, int], int] = {}
    nxt = 1
    for j, (a, b) in enumerate(zip(cuts[:-1], cuts[1:])):
        for k in range(road.num_lanes):
            if road.lane_exists(np.array([k]), np.array([0.5 * (a + b)]))[0]:
                ids[(k, j)] = nxt
                nxt += 1
    lanelets = []
    for (k, j), lid in ids.items():
        a, b = cuts[j], cuts[j + 1]
        s = np.linspace(a, b, max(2, int(math.ceil((b - a) / LANELET_STEP_M)) + 1))
        dr, dl = road.lane_bounds_d(np.full(s.shape, k), s)
        # at a stretch's end, the borders of the lane as it is there (lane_bounds_d looks ahead at a cut)
        dr_end, dl_end = road.lane_bounds_d(np.array([k]), np.array([b - 1e-6]))
        dr[-1], dl[-1] = dr_end[0], dl_end[0]
        xr, yr, _ = road.frenet_to_cartesian(s, dr)
        xl, yl, _ = road.frenet_to_cartesian(s, dl)
        left, right = np.column_stack([xl, yl]), np.column_stack([xr, yr])
        lanelets.append(Lanelet(left, 0.5 * (left + right), right, lid,
                                predecessor=[ids[(k, j - 1)]] if (k, j - 1) in ids else None,
                                successor=[ids[(k, j + 1)]] if (k, j + 1) in ids else None,
                                adjacent_left=ids.get((k + 1, j)), adjacent_left_same_direction=(k + 1, j) in ids or None,
                                adjacent_right=ids.get((k - 1, j)),
                                adjacent_right_same_direction=(k - 1, j) in ids or None,
                                lanelet_type={LaneletType.HIGHWAY}))
    return LaneletNetwork.create_from_lanelet_list(lanelets), ids


PLANNING_PROBLEM_ID = 999
"""Id of the SUT's planning problem (below every obstacle's, above every lanelet's on the shipped map)."""


def protobuf_runtime() -> None:
    """Make commonroad-io importable beside a newer protobuf than its generated modules were made for (it
    pins 3.20.2, ray needs a newer one: docs/export.md "Packages"): protobuf's pure-Python implementation,
    chosen by its environment variable before protobuf picks one; RuntimeError if it picked another."""
    import importlib
    import os
    import sys

    if "google.protobuf.internal.api_implementation" not in sys.modules:  # it reads the variable when imported
        os.environ["PROTOCOL_BUFFERS_PYTHON_IMPLEMENTATION"] = "python"
    if (kind := importlib.import_module("google.protobuf.internal.api_implementation").Type()) != "python":
        raise RuntimeError(f"protobuf was imported with its {kind!r} implementation before commonroad-io; start "
                           "Python with PROTOCOL_BUFFERS_PYTHON_IMPLEMENTATION=python (docs/export.md \"Packages\")")


def read_commonroad(path: Path | str):
    """``(scenario, planning problem set)`` of a CommonRoad file read by commonroad-io's
    ``CommonRoadFileReader``, protobuf's implementation chosen first (:func:`protobuf_runtime`)."""
    protobuf_runtime()
    from commonroad.common.file_reader import CommonRoadFileReader

    return CommonRoadFileReader(str(path)).open()


def _orientation(h: float) -> float:
    """``h`` wrapped to (-pi, pi] (CommonRoad checks orientations against +-2 pi)."""
    return float(math.atan2(math.sin(h), math.cos(h)))


def obstacle_id(vid: int, piece: int) -> int:
    """CommonRoad id of piece ``piece`` of vehicle ``vid`` (lanelets have ids below 1000)."""
    return 1000 * (vid + 1) + piece


def write_commonroad(ex: RangeExport, out_dir: Path | str, name: str = "scenario") -> Path:
    """``out_dir/<name>.xml``: the map's lanelets, every BV piece a dynamic obstacle (car or truck,
    rectangle of its size, its states from the piece's first to its last step), and a planning
    problem for the SUT: its first state and, as goal, the rectangle of its pose at the end of its
    first piece (±1 m along and across, heading ±0.1 rad) in that time step. Returns the file."""
    protobuf_runtime()
    import shapely
    from commonroad.common.common_scenario import ScenarioID
    from commonroad.common.file_writer import CommonRoadFileWriter
    from commonroad.common.util import AngleInterval, FileFormat, Interval
    from commonroad.common.writer.file_writer_interface import OverwriteExistingFile
    from commonroad.geometry.obstacle_shapes.rect_obstacle_shape import RectObstacleShape
    from commonroad.geometry.occupancy.rect_occupancy import RectOccupancy
    from commonroad.planning.goal import GoalRegion
    from commonroad.planning.planning_problem import PlanningProblem, PlanningProblemSet
    from commonroad.prediction.prediction import TrajectoryPrediction
    from commonroad.scenario.obstacle import DynamicObstacle, ObstacleType
    from commonroad.scenario.scenario import Scenario, Tag
    from commonroad.scenario.state import CustomState, InitialState
    from commonroad.scenario.trajectory import Trajectory
    from evoscen_sim.road.road_model import load_road

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    road = load_road(ex.map_path)
    scenario = Scenario(ex.dt_s, ScenarioID(country_id="ZAM", map_name="evoscenOnramp", map_id=1))
    network, _ = lanelet_network(road)
    scenario.add_objects(network)
    for tr in ex.tracks:
        if tr.role == C.ROLE_SUT:
            continue
        kind = ObstacleType.TRUCK if tr.klass == "truck" else ObstacleType.CAR
        shape = RectObstacleShape(tr.width_m, tr.length_m)
        for n, p in enumerate(tr.pieces):
            def state(i: int, cls=CustomState, p=p):
                return cls(position=np.array([p.x[i], p.y[i]]), orientation=_orientation(p.yaw[i]),
                           velocity=float(p.speed[i]), acceleration=float(p.accel[i]), time_step=p.k0 + i,
                           **({"yaw_rate": 0.0, "slip_angle": 0.0} if cls is InitialState else {}))
            init = state(0, InitialState)
            prediction = None
            if p.steps >= 2:
                traj = Trajectory(p.k0 + 1, [state(i) for i in range(1, p.steps)])
                prediction = TrajectoryPrediction(traj, shape)
            scenario.add_objects(DynamicObstacle(obstacle_id(tr.vid, n), kind, shape, init, prediction))
    sut = ex.sut
    p = sut.pieces[0]
    start = InitialState(position=np.array([p.x[0], p.y[0]]), orientation=_orientation(p.yaw[0]),
                         velocity=float(p.speed[0]),
                         acceleration=float(p.accel[0]), yaw_rate=0.0, slip_angle=0.0, time_step=0)
    last = p.steps - 1
    goal_shape = RectOccupancy(shapely.Point(float(p.x[last]), float(p.y[last])), 2.0 + sut.width_m,
                               2.0 + sut.length_m, _orientation(float(p.yaw[last])))
    goal_state = CustomState(position=goal_shape, orientation=AngleInterval(_orientation(float(p.yaw[last])) - 0.1,
                                                                             _orientation(float(p.yaw[last])) + 0.1),
                             time_step=Interval(p.k0 + last, p.k0 + last))
    problems = PlanningProblemSet([PlanningProblem(PLANNING_PROBLEM_ID, start, GoalRegion([goal_state]))])
    path = out_dir / f"{name}.xml"
    path.unlink(missing_ok=True)  # the writer asks (on stdout) before it replaces a file
    CommonRoadFileWriter(scenario, problems, author="evoscen", affiliation="evoscen",
                         source=f"evoscen bag {ex.bag.name} from t = {ex.t_from_s:.1f} s", tags={Tag.HIGHWAY},
                         decimal_precision=6, file_format=FileFormat.XML,
                         ).write_to_file(str(path), OverwriteExistingFile.ALWAYS)
    return path


def check_commonroad(ex: RangeExport, path: Path | str) -> tuple[int, int, list[str]]:
    """Read ``path`` back with commonroad-io's ``CommonRoadFileReader`` and compare it with what
    :func:`write_commonroad` wrote for ``ex``: one dynamic obstacle per BV piece (same ids, first and
    last time steps), the scenario's time steps (its last = ``ex.states - 1``), ``dt``, and the SUT's
    planning problem starting at time step 0. Returns ``(obstacles, time steps, problems)``: the
    counts read back and one line per difference (empty: the file holds what was exported)."""
    scenario, problems = read_commonroad(path)
    want = {obstacle_id(t.vid, n): (p.k0, p.k0 + p.steps - 1)
            for t in ex.tracks if t.role != C.ROLE_SUT for n, p in enumerate(t.pieces)}
    got = {o.obstacle_id: (o.initial_state.time_step,
                           o.prediction.final_time_step if o.prediction is not None else o.initial_state.time_step)
           for o in scenario.dynamic_obstacles}
    steps = 1 + max([last for _, last in got.values()] + [0])
    out = []
    if sorted(got) != sorted(want):
        out.append(f"obstacles: read back {len(got)}, exported {len(want)} "
                   f"(missing {sorted(set(want) - set(got))[:5]}, extra {sorted(set(got) - set(want))[:5]})")
    out += [f"obstacle {i}: time steps {got[i][0]}..{got[i][1]} read back, {want[i][0]}..{want[i][1]} exported"
            for i in sorted(set(got) & set(want)) if got[i] != want[i]]
    if steps != ex.states:
        out.append(f"time steps: read back {steps}, exported {ex.states}")
    if abs(float(scenario.dt) - ex.dt_s) > 1e-9:
        out.append(f"dt: read back {scenario.dt}, exported {ex.dt_s}")
    pps = list(problems.planning_problem_dict.values())
    if [pp.planning_problem_id for pp in pps] != [PLANNING_PROBLEM_ID] or pps[0].initial_state.time_step != 0:
        out.append(f"planning problem: expected one (id {PLANNING_PROBLEM_ID}) starting at time step 0")
    return len(got), steps, out


# ---------------------------------------------------------------------------------- a start from a file


@dataclass
class ImportedStart:
    """An exported scenario's ``Init`` as evoscen's start (:func:`initial_state_from_xosc`)."""

    ids: np.ndarray
    roles: np.ndarray
    policies: np.ndarray
    s_m: np.ndarray
    d_m: np.ndarray
    heading_rel: np.ndarray
    """Heading relative to the road at ``s`` (rad, positive to the left)."""
    lane: np.ndarray
    speed_mps: np.ndarray
    length_m: np.ndarray
    width_m: np.ndarray
    classes: list[str]


def initial_state_from_xosc(path: Path | str, road) -> ImportedStart:
    """The vehicles of an OpenSCENARIO file's ``Init`` (evoscen's export or any file whose entities
    are vehicles placed by a WorldPosition teleport and an absolute speed) in evoscen's terms: the
    SUT (entity ``sut``, or property ``evoscen:role`` = sut) first, then the others by id
    (``evoscen:id`` or the order in the file); ``s``, ``d`` from the road model's
    ``cartesian_to_frenet``, the lane that holds ``d``.

    Raises:
        InputError: unreadable file, no SUT or no vehicles, a vehicle off the road.
    """
    path = Path(path)
    try:
        tracks = read_xosc_tracks(path)
    except (OSError, ET.ParseError, AttributeError, TypeError, ValueError, KeyError) as exc:
        raise InputError(f"--start-from {path}: not a readable OpenSCENARIO file of vehicles placed by WorldPosition "
                         f"({type(exc).__name__}: {exc})") from None
    rows = []
    for order, tr in enumerate(tracks.values()):
        is_sut = tr.name == SUT_NAME or tr.properties.get("evoscen:role") == "sut"
        vid = int(tr.properties.get("evoscen:id", -1))
        rows.append((0 if is_sut else 1, vid if vid >= 0 else order, tr, is_sut))
    rows.sort(key=lambda r: (r[0], r[1]))
    if not rows or rows[0][0] != 0 or sum(r[3] for r in rows) != 1:
        raise InputError(f"--start-from {path}: entities: expected exactly one SUT (entity 'sut' or property "
                         "evoscen:role = sut)")
    x = np.array([r[2].init_pose[0] for r in rows])
    y = np.array([r[2].init_pose[1] for r in rows])
    s, d = road.cartesian_to_frenet(x, y)
    lane = road.lane_of(s, d)
    for r, sv, ln in zip(rows, s, lane):
        if ln < 0 or not 0.0 <= sv <= road.length_m:
            raise InputError(f"--start-from {path}: entity {r[2].name!r}: position {r[2].init_pose[:2]} is off the "
                             "road (expected a point inside a lane of the map)")
    ids = np.array([r[1] for r in rows], dtype=np.int64)
    if len(set(ids.tolist())) != len(ids):
        raise InputError(f"--start-from {path}: entities: duplicated vehicle ids {ids.tolist()}")
    return ImportedStart(
        ids=ids, roles=np.array([C.ROLE_SUT if r[3] else C.ROLE_BV for r in rows], dtype=np.int64),
        policies=np.array([policy_code(r[2].properties.get("evoscen:policy")) for r in rows], dtype=np.int64),
        s_m=s, d_m=d, heading_rel=np.angle(np.exp(1j * (np.array([r[2].init_pose[2] for r in rows])
                                                           - road.frenet_to_cartesian(s, d)[2]))),
        lane=lane.astype(np.int64), speed_mps=np.array([r[2].init_speed for r in rows]),
        length_m=np.array([r[2].length_m for r in rows]), width_m=np.array([r[2].width_m for r in rows]),
        classes=[r[2].category for r in rows])


START_TOLERANCE_M = 0.01
START_TOLERANCE_MPS = 0.01
"""How far a run started from an export may be from the range's first state (position m, speed m/s)."""


def compare_start(ex: RangeExport, run_bag: Path | str, truck_min_length_m: float = TRUCK_MIN_LENGTH_M
                  ) -> tuple[int, list[str]]:
    """The first state of ``run_bag`` (a run started with ``--start-from`` the export of ``ex``)
    against the range's first state: the same vehicle ids, and for each its role, class, lane,
    position (``x``, ``y`` within :data:`START_TOLERANCE_M`) and speed (within
    :data:`START_TOLERANCE_MPS`). Returns ``(vehicles compared, one line per difference)``."""
    from evoscen_eval.scoring.rundata import read_run

    run = read_run(run_bag)
    col = {f: run.columns[f][0] for f in ("x", "y", "speed", "role", "lane", "length")}
    got = {int(vid): v for v, vid in enumerate(run.ids.tolist())}
    out = []
    want = {t.vid: t for t in ex.tracks}
    if sorted(got) != sorted(want):
        out.append(f"vehicle ids: run {sorted(got)}, export {sorted(want)}")
    for vid in sorted(set(got) & set(want)):
        t, v, p = want[vid], got[vid], want[vid].pieces[0]
        klass = vehicle_class(float(col["length"][v]), truck_min_length_m)
        if int(col["role"][v]) != t.role or klass != t.klass or int(col["lane"][v]) != t.lane0:
            out.append(f"vehicle {vid}: role/class/lane {int(col['role'][v])}/{klass}/{int(col['lane'][v])}, "
                       f"export {t.role}/{t.klass}/{t.lane0}")
        dxy = math.hypot(float(col["x"][v]) - p.x[0], float(col["y"][v]) - p.y[0])
        if dxy > START_TOLERANCE_M:
            out.append(f"vehicle {vid}: position {dxy:.4f} m from the export's")
        dv = abs(float(col["speed"][v]) - p.speed[0])
        if dv > START_TOLERANCE_MPS:
            out.append(f"vehicle {vid}: speed {dv:.4f} m/s from the export's")
    return len(set(got) & set(want)), out
