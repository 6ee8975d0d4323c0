"""SUMO's own driver as an evoscen SUT: Krauss car following and LC2013 (or SL2015) lane changing,
run by SUMO itself through libsumo (docs/plugins.md, "Example: SUMO's own driver as the SUT").

The SUT is a vehicle in a SUMO network of the same road: the scenario's OpenDRIVE map converted by
``netconvert`` (cached by the map's content and the conversion options). Every step:

1. every vehicle of the view is placed in SUMO where evoscen has it (``vehicle.moveTo``: the lane and
   the front bumper's position along it) with its speed (``vehicle.setPreviousSpeed``); the other
   vehicles then hold that speed through the step (speed mode 0) and never change lanes in SUMO; the
   SUT is placed in its ``target_lane`` while a lane change is under way;
2. SUMO steps once (``simulationStep``, step length ``dt_s``): Krauss chooses the SUT's speed, the
   lane-change model its lane;
3. speed -> acceleration ``(v_sumo - v) / dt_s`` -> throttle (``accel_to_throttle``, the scenario's
   vehicle limits); a lane SUMO changed to -> a lane-change request of ±1 (none while evoscen is still
   executing a change). With SL2015 (sublane model) a change is a lateral movement over several
   steps: the request is the direction the model wants and may move (``getLaneChangeState``).

The traffic window's shift and new trips need no memory here: every vehicle is placed afresh each
step, wherever it is (a BV off SUMO's network -- waiting before the road's start, past its end, or in
the merge lane's taper, which SUMO reserves for emergency vehicles -- is taken out of SUMO until it is
back on it).

libsumo is one SUMO simulation per process. A driver starts its simulation at its first ``act``; a
second driver that starts one in the same process closes the first one's, and the first one, asked
to act again, stops with one line (:class:`SumoInstanceError`). So: one SUMO SUT per process (the
node graph's SUT node and the in-process runner have one; campaigns run one run at a time per Ray
worker process).

Eclipse SUMO is licensed under EPL-2.0; this module only calls it.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import math
import os
import shutil
import subprocess
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from evoscen import InputError, ModelSpec, accel_to_throttle, load_road, number, resolve_map_path, text

NAME = "sumo_sut"
SUMO_VERSION = "1.28.0"
#: netconvert options of the conversion (part of the cache key). The merge lane's taper is narrower
#: than --opendrive.min-width (1.8 m) from s = 927.9 m: SUMO makes it an emergency lane there.
NETCONVERT_OPTIONS = ("--opendrive.import-all-lanes", "false", "--no-turnarounds", "true", "--offset.disable-normalization", "true")
SUT_ID = "sut"
ROUTE_ID = "road"
#: vehicle.moveTo's reason: a normal move (TraCI's MOVE_NORMAL). SUMO treats a long automatic move as a
#: teleport and resets the lane-change model's memory (LC2013's speed-gain wish), which would make the
#: traffic window's shift (1700 m back) delay the SUT's next change by about 1 s.
MOVE_REASON = 2


class SumoInstanceError(RuntimeError):
    """A second SUMO simulation in one process took libsumo from this driver (one line)."""


@dataclass(frozen=True)
class SumoSutParams:
    """``models.sumo_sut`` in the scenario YAML. Defaults: SUMO's own (sumo.dlr.de, vType attributes)."""

    lane_change_model: str = text("LC2013", ("LC2013", "SL2015"))
    """SUMO's lane-change model: LC2013 (lanes) or SL2015 (sublanes, with ``lateral_resolution_m``)."""
    accel_mps2: float = number(2.6, 0.0, 10.0, lo_open=True)
    """Krauss ``accel`` (m/s²); SUMO's passenger default. evoscen clips to vehicle.max_accel_mps2 (3)."""
    decel_mps2: float = number(4.5, 0.0, 10.0, lo_open=True)
    """Krauss ``decel``, the comfortable deceleration (m/s²); SUMO's default."""
    emergency_decel_mps2: float = number(9.0, 0.0, 20.0, lo_open=True)
    """Krauss ``emergencyDecel`` (m/s²); SUMO's default. evoscen clips to vehicle.max_brake_mps2 (8)."""
    sigma: float = number(0.5, 0.0, 1.0)
    """Krauss dawdling ``sigma`` (–); SUMO's default. Drawn from SUMO's generator, seeded from ``rng``."""
    tau_s: float = number(1.0, 0.0, 10.0, lo_open=True)
    """Krauss ``tau``, the desired time headway (s); SUMO's default."""
    min_gap_m: float = number(2.5, 0.0, 50.0)
    """``minGap``, the standstill gap (m); SUMO's default."""
    speed_factor: float = number(1.0, 0.1, 2.0)
    """Desired speed as a multiple of the lane's speed limit (–); fixed (no speedDev)."""
    lc_strategic: float = number(1.0, 0.0, 100.0)
    """``lcStrategic``: eagerness for changes needed by the route (the merge) (–); SUMO's default."""
    lc_cooperative: float = number(1.0, 0.0, 1.0)
    """``lcCooperative``: willingness to make room for others (–); SUMO's default."""
    lc_speed_gain: float = number(1.0, 0.0, 100.0)
    """``lcSpeedGain``: eagerness to change for a higher speed (–); SUMO's default."""
    lc_keep_right: float = number(1.0, 0.0, 100.0)
    """``lcKeepRight``: eagerness to return to the right (–); SUMO's default."""
    lateral_resolution_m: float = number(0.8, 0.1, 3.5)
    """SL2015 only: SUMO's ``--lateral-resolution``, the sublane width (m); SUMO's recommended 0.8."""


# ------------------------------------------------------------------ SUMO: finding, importing, converting


def _import_libsumo():
    """libsumo, imported quietly (its import prints a pyarrow version warning to stdout)."""
    with contextlib.redirect_stdout(io.StringIO()):
        import libsumo
    return libsumo


def netconvert_path() -> str:
    """netconvert of the eclipse-sumo wheel, else SUMO_HOME/bin, else PATH."""
    candidates = []
    with contextlib.suppress(ImportError):
        import sumo

        candidates.append(Path(getattr(sumo, "SUMO_HOME", os.path.dirname(sumo.__file__))) / "bin" / "netconvert")
    if os.environ.get("SUMO_HOME"):
        candidates.append(Path(os.environ["SUMO_HOME"]) / "bin" / "netconvert")
    for cand in candidates:
        if cand.is_file() and os.access(cand, os.X_OK):
            return str(cand)
    found = shutil.which("netconvert")
    if found is None:
        raise InputError(f"{NAME}: netconvert not found (pip install eclipse-sumo=={SUMO_VERSION}, or set SUMO_HOME)")
    return found


def cache_dir() -> Path:
    """Where converted networks are kept: $EVOSCEN_SUMO_CACHE, else $XDG_CACHE_HOME (~/.cache)/evoscen/sumo_sut."""
    if os.environ.get("EVOSCEN_SUMO_CACHE"):
        return Path(os.environ["EVOSCEN_SUMO_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "evoscen" / "sumo_sut"


def convert_map(xodr: Path) -> Path:
    """The SUMO network of the OpenDRIVE map ``xodr``: converted once, then taken from the cache
    (keyed by the map's bytes, SUMO's version and the options). A failure is one line (InputError)."""
    try:
        data = xodr.read_bytes()
    except OSError as exc:
        raise InputError(f"{xodr}: cannot read the map for the SUMO SUT: {exc.strerror or exc}") from None
    key = hashlib.sha256(data + repr((SUMO_VERSION, NETCONVERT_OPTIONS)).encode()).hexdigest()[:16]
    folder = cache_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        folder = Path(tempfile.gettempdir()) / "evoscen-sumo-sut"
        folder.mkdir(parents=True, exist_ok=True)
    net = folder / f"{xodr.stem}-{key}.net.xml"
    if net.is_file():
        return net
    partial = Path(tempfile.mkstemp(dir=folder, prefix=net.stem, suffix=".part.xml")[1])
    try:
        res = subprocess.run([netconvert_path(), "--opendrive-files", str(xodr), "--output-file", str(partial),
                              "--no-warnings", "true", *NETCONVERT_OPTIONS],
                             capture_output=True, text=True, check=False, timeout=120)
        if res.returncode != 0:
            lines = [line.strip() for line in (res.stderr + res.stdout).splitlines() if line.strip()]
            reason = lines[-1] if lines else f"exit status {res.returncode}"
            raise InputError(f"{xodr}: netconvert could not convert the map for the SUMO SUT: {reason}")
        os.replace(partial, net)  # atomic: concurrent workers converting the same map agree
    finally:
        with contextlib.suppress(OSError):
            partial.unlink()
    return net


# ------------------------------------------------------------------ the network: evoscen (s, lane) <-> SUMO


def _polyline(shape: str) -> np.ndarray:
    return np.array([[float(c) for c in p.split(",")[:2]] for p in shape.split()])


def _midpoint(xy: np.ndarray) -> np.ndarray:
    seg = np.hypot(*np.diff(xy, axis=0).T)
    if seg.sum() == 0.0:
        return xy[0]
    at = 0.5 * seg.sum()
    k = int(np.searchsorted(np.cumsum(seg), at))
    before = np.cumsum(seg)[k] - seg[k]
    t = (at - before) / seg[k] if seg[k] > 0 else 0.0
    return xy[k] + t * (xy[k + 1] - xy[k])


class SumoNetwork:
    """The converted network, seen from evoscen: which SUMO lane and position is (lane, s)."""

    def __init__(self, net: Path, road) -> None:  # a RoadModel
        root = ET.parse(net).getroot()
        loc = root.find("location")
        offset = np.array([float(c) for c in loc.get("netOffset", "0,0").split(",")]) if loc is not None else np.zeros(2)
        self.lane_of: dict[str, int] = {}  # every SUMO lane (internal ones too) -> evoscen lane
        spans: dict[int, list[tuple[float, float, str, float]]] = {k: [] for k in range(road.num_lanes)}
        edges: list[tuple[float, str]] = []
        for edge in root.iter("edge"):
            internal = edge.get("function") == "internal"
            starts = []
            for lane in edge.iter("lane"):
                xy = _polyline(lane.get("shape")) - offset
                s_mid, d_mid = (float(a) for a in road.cartesian_to_frenet(*_midpoint(xy)))
                index = int(road.lane_of(s_mid, d_mid))
                if index < 0:
                    continue
                self.lane_of[lane.get("id")] = index
                allow, disallow = lane.get("allow"), lane.get("disallow") or ""
                if internal or (allow is not None and "passenger" not in allow.split()) or "passenger" in disallow.split():
                    continue
                s0 = float(road.cartesian_to_frenet(*xy[0])[0])
                s1 = float(road.cartesian_to_frenet(*xy[-1])[0])
                spans[index].append((s0, s1, lane.get("id"), float(lane.get("length"))))
                starts.append(s0)
            if starts:
                edges.append((min(starts), edge.get("id")))
        self.route = [e for _, e in sorted(edges)]
        self.spans = {k: sorted(v) for k, v in spans.items()}

    def place(self, lane: int, s_front: float, clamp: bool) -> tuple[str, float] | None:
        """(SUMO lane id, position of the front bumper on it) for evoscen ``lane`` at ``s_front``; None
        where SUMO has no such lane there (``clamp``: the nearest end of the lane's nearest piece instead)."""
        spans = self.spans.get(lane) or []
        best, best_dist = None, math.inf
        for s0, s1, lane_id, length in spans:
            if s0 <= s_front <= s1:
                return lane_id, (s_front - s0) / (s1 - s0) * length
            dist = s0 - s_front if s_front < s0 else s_front - s1
            if dist < best_dist:
                best, best_dist = (lane_id, 0.0 if s_front < s0 else length), dist
        # a junction's few metres between two pieces of the same lane: its nearest end
        if best is not None and (clamp or best_dist <= 10.0):
            return best
        return None


# ------------------------------------------------------------------ the driver

_OWNER: list = [None]  # the driver whose simulation libsumo holds in this process


class SumoSut:
    """The driver: SUMO decides for vehicle ``vehicles[0]`` (the SUT) among the view's vehicles."""

    def __init__(self, vehicles: np.ndarray, params: SumoSutParams, config, seed: int, net: Path, road) -> None:
        self.vehicles = np.asarray(vehicles, dtype=np.int64)
        self.p = params
        self.vehicle = config.vehicle
        self.dt_s = float(config.dt_s)
        self.seed = int(seed)
        self.net_path = net
        self.net = SumoNetwork(net, road)
        self.present: set[str] = set()
        self.started = False
        self.lost = False
        self._tmp: tempfile.TemporaryDirectory | None = None
        self.sumo = None

    # -- the simulation
    def _routes_file(self) -> str:
        p, veh = self.p, self.vehicle
        self._tmp = tempfile.TemporaryDirectory(prefix="evoscen-sumo-sut-")
        path = os.path.join(self._tmp.name, "types.rou.xml")
        lc = (f'laneChangeModel="{p.lane_change_model}" lcStrategic="{p.lc_strategic!r}" '
              f'lcCooperative="{p.lc_cooperative!r}" lcSpeedGain="{p.lc_speed_gain!r}" lcKeepRight="{p.lc_keep_right!r}"')
        with open(path, "w", encoding="utf-8") as f:
            f.write(f'<routes>\n  <vType id="sut" carFollowModel="Krauss" accel="{p.accel_mps2!r}" decel="{p.decel_mps2!r}"'
                    f' emergencyDecel="{p.emergency_decel_mps2!r}" sigma="{p.sigma!r}" tau="{p.tau_s!r}"'
                    f' minGap="{p.min_gap_m!r}" length="{veh.length_m!r}" width="{veh.width_m!r}"'
                    f' maxSpeed="{veh.max_speed_mps!r}" speedFactor="{p.speed_factor!r}" speedDev="0" {lc}/>\n'
                    f'  <vType id="bv" length="{veh.length_m!r}" width="{veh.width_m!r}" maxSpeed="{veh.max_speed_mps!r}"'
                    f' speedDev="0" sigma="0" {lc}/>\n'
                    f'  <route id="{ROUTE_ID}" edges="{" ".join(self.net.route)}"/>\n</routes>\n')
        return path

    def _start(self) -> None:
        libsumo = _import_libsumo()
        owner = _OWNER[0]
        if owner is not None and owner is not self:
            owner.release(lost=True)
        args = ["sumo", "-n", str(self.net_path), "-r", self._routes_file(), "--step-length", repr(self.dt_s),
                "--seed", str(self.seed), "--no-step-log", "true", "--no-warnings", "true",
                "--duration-log.disable", "true", "--time-to-teleport", "-1", "--collision.action", "none",
                "--collision.check-junctions", "false", "--ignore-route-errors", "true"]
        if self.p.lane_change_model == "SL2015":
            args += ["--lateral-resolution", repr(self.p.lateral_resolution_m)]
        with contextlib.redirect_stdout(io.StringIO()):
            libsumo.start(args)
        _OWNER[0] = self
        self.sumo = libsumo
        self.started = True

    def release(self, lost: bool = False) -> None:
        """Close this driver's simulation (``lost``: another driver took libsumo)."""
        if _OWNER[0] is self and self.sumo is not None:
            with contextlib.suppress(Exception):
                self.sumo.close()
            _OWNER[0] = None
        self.lost = self.lost or lost
        self.present.clear()
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None

    def _put(self, vid: str, type_id: str, place: tuple[str, float] | None, speed: float, accel: float) -> None:
        """Vehicle ``vid`` to ``place`` at ``speed`` (taken out of SUMO where ``place`` is None)."""
        veh = self.sumo.vehicle
        if place is None:
            if vid in self.present:
                veh.remove(vid)
                self.present.discard(vid)
            return
        if vid not in self.present:
            veh.add(vid, ROUTE_ID, typeID=type_id, depart="now", departSpeed="0")
            if type_id == "bv":  # driven by evoscen: no own speed choice, no lane change in SUMO
                veh.setLaneChangeMode(vid, 0)
                veh.setSpeedMode(vid, 0)
            self.present.add(vid)
        lane_id, pos = place
        veh.moveTo(vid, lane_id, pos, MOVE_REASON)
        veh.setPreviousSpeed(vid, speed, accel)
        if type_id == "bv":
            veh.setSpeed(vid, speed)

    # -- the protocol
    def act(self, view):  # view: a traffic view (evoscen.TrafficView)
        if self.lost:
            raise SumoInstanceError(f"{NAME}: another SUMO SUT started in this process and took libsumo from this "
                                    "one: libsumo runs one SUMO simulation per process (one SUMO SUT per process)")
        if not self.started:
            self._start()
        sut = int(self.vehicles[0])
        half = 0.5 * np.asarray(view.length, dtype=float)
        placed_lane = int(view.target_lane[sut])  # during a change SUMO sees the SUT where it is heading
        for i in range(int(view.n)):
            mine = i == sut
            lane = placed_lane if mine else int(view.lane[i])
            place = self.net.place(lane, float(view.s[i] + half[i]), clamp=mine)
            self._put(SUT_ID if mine else f"v{i}", "sut" if mine else "bv", place, float(view.v[i]),
                      float(view.accel[i]))
        self.sumo.simulationStep()
        for vid in self.sumo.simulation.getArrivedIDList():
            self.present.discard(vid)
        veh = self.sumo.vehicle
        v_next = float(veh.getSpeed(SUT_ID))
        accel = (v_next - float(view.v[sut])) / self.dt_s
        request = 0
        if int(view.lane_change[sut]) == 0:
            sumo_lane = self.net.lane_of.get(veh.getLaneID(SUT_ID), placed_lane)
            request = int(np.clip(sumo_lane - placed_lane, -1, 1))
            if request == 0 and self.p.lane_change_model == "SL2015":
                request = self._sublane_request()
        return accel_to_throttle(np.array([accel]), self.vehicle), np.array([request], dtype=np.int64)

    def _sublane_request(self) -> int:
        """SL2015: the direction the model wants and may move in now (+1 left, -1 right, 0 none)."""
        tc = self.sumo.constants
        for direction, bit in ((1, tc.LCA_LEFT), (-1, tc.LCA_RIGHT)):
            state = self.sumo.vehicle.getLaneChangeState(SUT_ID, direction)[0]
            if state & bit and not state & tc.LCA_BLOCKED:
                return direction
        return 0

    def __del__(self) -> None:
        with contextlib.suppress(Exception):
            self.release()


def make(vehicles: np.ndarray, params: SumoSutParams, config, rng: np.random.Generator) -> SumoSut:
    """The factory: converts (or takes from the cache) the map; SUMO itself starts at the first ``act``."""
    xodr = resolve_map_path(config.map)
    net = convert_map(Path(xodr))
    seed = int(rng.integers(0, 2**31 - 1))  # SUMO's --seed: its dawdling and lane-change draws
    driver = SumoSut(vehicles, params, config, seed, net, load_road(xodr))
    missing = [lane for lane, spans in driver.net.spans.items() if not spans]
    if missing:
        raise InputError(f"{xodr}: its SUMO network ({net}) has no car lane for evoscen lane(s) "
                         f"{', '.join(map(str, missing))}: the SUMO SUT needs every lane of the map in SUMO")
    return driver


SPEC = ModelSpec(name=NAME, roles=("sut",), factory=make, params_type=SumoSutParams,
                 description="SUMO's own driver through libsumo: Krauss + LC2013 (or SL2015)")
