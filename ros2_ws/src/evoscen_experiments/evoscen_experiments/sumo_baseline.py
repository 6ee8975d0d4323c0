"""SUMO baseline: stepping rate of SUMO (libsumo) on the evoscen highway-merge scenario
(``scripts/sumo_baseline.py``, and the reference of ``scripts/bench.py``).

Used by the benchmark to put evoscen's own stepping rate next to a well-known microscopic
simulator on the *same road and traffic volume*. SUMO is an OPTIONAL dependency: only the
benchmark imports this module, and importing it does not import SUMO (``sumo_available()``
tells whether a measurement is possible).

Install (kept out of the project requirements, e.g. in a separate venv)::

    pip install eclipse-sumo libsumo    # tested with 1.28.0 (sumolib/traci 1.28.0 too)

Scenario mapping (evoscen -> SUMO)
----------------------------------
* Road: one-way highway, total length 2393.76 m, lanes 3.5 m wide, speed limit
  120 km/h = 33.33 m/s on every lane. Built from plain XML (nodes + edges + explicit
  connections) with ``netconvert`` in a temporary directory, three mainline edges in a
  straight line (edge lengths forced with the ``length`` attribute, junctions with
  ``--no-internal-links`` so that the total length is exactly that of evoscen):

  ===========  ==============  =======  =========================================
  SUMO edge    s range (m)     lanes    evoscen lanes
  ===========  ==============  =======  =========================================
  ``up``       0 - 600         4        II..V  (SUMO lane 0..3)
  ``acc``      600 - 960       5        I..V   (SUMO lane 0 = lane I = merge lane)
  ``down``     960 - 2393.76   4        II..V  (SUMO lane 0..3)
  ``ramp``     (on-ramp)       1        feeds lane I at s = 600 m
  ===========  ==============  =======  =========================================

  SUMO numbers lanes from the right (lane 0 = rightmost), like evoscen's lane index
  (0 = lane I, the merge lane, rightmost), so on ``acc`` SUMO lane i == evoscen index i
  and on ``up``/``down`` SUMO lane i == evoscen index i + 1. The acceleration lane
  (``acc`` lane 0) has no successor: vehicles on it must change left before s = 960 m
  (SUMO's strategic lane changing does that, as a merging driver would). The on-ramp
  (200 m, 1 lane, same speed limit) connects only to ``acc`` lane 0.
* Traffic: ``vehicles`` vehicles (default 21 = 20 background + 1 SUT), SUMO's default
  vehicle type (passenger car, Krauss car following, LC2013 lane changing, default
  speed-factor distribution). Background vehicles drive the mainline
  ``up -> acc -> down``; the vehicle ``sut`` drives ``ramp -> acc -> down`` (it merges).
  At t = 0 the background vehicles are spread evenly over the whole mainline
  (lanes cycled), the SUT is at the start of the ramp.
* Constant volume: whenever a vehicle leaves the road (arrives at the end of ``down``)
  it is re-inserted at once, with the same id, at the start of its route
  (``traci.vehicle.add`` via libsumo, departLane "best", departSpeed "max"). The number
  of vehicles on the road therefore stays at ``vehicles`` (minus the few waiting in the
  insertion queue when the entry is momentarily blocked); ``mean_vehicles`` reports it.
* Step length 0.1 s (evoscen's dt), no GUI, deterministic (``--seed``), collisions
  reported as warnings only, no teleporting of jammed vehicles.

Timing: only the stepping loop is timed: the sum over the measured steps of
``time.perf_counter()`` around ``libsumo.simulationStep()``, after ``warmup_steps``
un-timed steps, with the network already built and the vehicles already inserted.
The per-step bookkeeping of the harness (counting vehicles, re-inserting arrived
ones) is outside that sum; ``loop_steps_per_s`` (extra key) also includes it.

libsumo and restarts: libsumo is an in-process singleton (one simulation per process;
some SUMO versions cannot ``start`` again after ``close`` in the same process, and a
caller may have a simulation of its own loaded). ``measure_sumo_steps_per_second``
therefore runs, by default, in a fresh child process (the same interpreter, this process's
import path, :data:`CHILD`); the figures are measured inside the child, so the process
start-up does not enter them. ``in_process=True`` runs it here instead.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

# --- scenario constants (evoscen highway-merge road) -------------------------------------
ROAD_LENGTH_M = 2393.76
MERGE_START_M = 600.0
MERGE_END_M = 960.0
MAIN_LANES = 4
LANE_WIDTH_M = 3.5
SPEED_LIMIT_MPS = 120.0 / 3.6  # 33.33 m/s
RAMP_LENGTH_M = 200.0
STEP_LENGTH_S = 0.1

ROUTE_MAIN = "r_main"  # up acc down
ROUTE_RAMP = "r_ramp"  # ramp acc down
SUT_ID = "sut"

CHILD = """
import json, sys
from evoscen_experiments.sumo_baseline import _measure_in_process
try:
    print(json.dumps(_measure_in_process(*map(int, sys.argv[1:5]))))
except (RuntimeError, ValueError) as exc:
    print(f"error: {exc}", file=sys.stderr)
    sys.exit(2)
"""
"""The child process of :func:`measure_sumo_steps_per_second`: one measurement (steps, vehicles, seed,
warm-up steps), printed as one JSON line."""


# --- locating SUMO -----------------------------------------------------------------------
def _sumo_home() -> str | None:
    """SUMO_HOME from the ``eclipse-sumo`` wheel (``sumo`` package), else the environment."""
    try:
        import sumo  # eclipse-sumo wheel

        home = getattr(sumo, "SUMO_HOME", None) or os.path.dirname(sumo.__file__)
        if home and os.path.isdir(home):
            return home
    except Exception:  # noqa: BLE001 (any failure: fall back to SUMO_HOME)
        pass
    home = os.environ.get("SUMO_HOME")
    return home if home and os.path.isdir(home) else None


def _find_netconvert() -> str | None:
    home = _sumo_home()
    if home:
        for name in ("netconvert", "netconvert.exe"):
            cand = os.path.join(home, "bin", name)
            if os.path.isfile(cand) and os.access(cand, os.X_OK):
                return cand
    # next to the running interpreter (console-script wrapper of the wheel), then PATH
    cand = os.path.join(os.path.dirname(sys.executable), "netconvert")
    if os.path.isfile(cand) and os.access(cand, os.X_OK):
        return cand
    return shutil.which("netconvert")


def sumo_available() -> tuple[bool, str]:
    """(True, description) when libsumo imports and netconvert is found, else (False, reason)."""
    try:
        import libsumo
    except Exception as exc:  # noqa: BLE001 -- ImportError, or a broken shared library
        return False, f"libsumo not importable ({type(exc).__name__}: {exc}); pip install eclipse-sumo libsumo"
    netconvert = _find_netconvert()
    if netconvert is None:
        return False, "netconvert not found (neither in the eclipse-sumo package, SUMO_HOME/bin nor PATH)"
    return True, f"libsumo {getattr(libsumo, '__version__', '?')}, netconvert {netconvert}"


def _sumo_env() -> dict:
    env = dict(os.environ)
    home = _sumo_home()
    if home:
        env["SUMO_HOME"] = home
    return env


# --- network -----------------------------------------------------------------------------
def _write_network(workdir: str) -> str:
    """Write plain XML, run netconvert, return the path of the .net.xml."""
    nod = os.path.join(workdir, "road.nod.xml")
    edg = os.path.join(workdir, "road.edg.xml")
    con = os.path.join(workdir, "road.con.xml")
    net = os.path.join(workdir, "road.net.xml")
    v = f"{SPEED_LIMIT_MPS:.4f}"
    w = f"{LANE_WIDTH_M}"
    # ramp start: upstream and to the right of the merge node, RAMP_LENGTH_M away (straight line)
    ramp_dy = -2.0 * LANE_WIDTH_M * 3
    ramp_dx = -((RAMP_LENGTH_M**2 - ramp_dy**2) ** 0.5)
    with open(nod, "w") as f:
        f.write(
            "<nodes>\n"
            '  <node id="n_start" x="0" y="0" type="priority"/>\n'
            f'  <node id="n_merge" x="{MERGE_START_M}" y="0" type="priority"/>\n'
            f'  <node id="n_accend" x="{MERGE_END_M}" y="0" type="priority"/>\n'
            f'  <node id="n_end" x="{ROAD_LENGTH_M}" y="0" type="priority"/>\n'
            f'  <node id="n_ramp" x="{MERGE_START_M + ramp_dx:.3f}" y="{ramp_dy:.3f}" type="priority"/>\n'
            "</nodes>\n"
        )
    with open(edg, "w") as f:
        f.write(
            "<edges>\n"
            f'  <edge id="up" from="n_start" to="n_merge" numLanes="{MAIN_LANES}" speed="{v}" width="{w}"'
            f' length="{MERGE_START_M}" priority="3"/>\n'
            f'  <edge id="acc" from="n_merge" to="n_accend" numLanes="{MAIN_LANES + 1}" speed="{v}" width="{w}"'
            f' length="{MERGE_END_M - MERGE_START_M}" priority="3"/>\n'
            f'  <edge id="down" from="n_accend" to="n_end" numLanes="{MAIN_LANES}" speed="{v}" width="{w}"'
            f' length="{ROAD_LENGTH_M - MERGE_END_M:.2f}" priority="3"/>\n'
            f'  <edge id="ramp" from="n_ramp" to="n_merge" numLanes="1" speed="{v}" width="{w}"'
            f' length="{RAMP_LENGTH_M}" priority="1"/>\n'
            "</edges>\n"
        )
    lines = ["<connections>"]
    for i in range(MAIN_LANES):  # mainline lanes keep their evoscen index across the merge
        lines.append(f'  <connection from="up" to="acc" fromLane="{i}" toLane="{i + 1}"/>')
        lines.append(f'  <connection from="acc" to="down" fromLane="{i + 1}" toLane="{i}"/>')
    lines.append('  <connection from="ramp" to="acc" fromLane="0" toLane="0"/>')
    lines.append("</connections>")
    with open(con, "w") as f:
        f.write("\n".join(lines) + "\n")

    netconvert = _find_netconvert()
    if netconvert is None:
        raise RuntimeError("netconvert not found")
    cmd = [
        netconvert,
        "--node-files", nod, "--edge-files", edg, "--connection-files", con,
        "--output-file", net,
        "--no-internal-links", "true",
        "--no-turnarounds", "true",
        "--offset.disable-normalization", "true",
        "--default.junctions.radius", "0",
        "--no-warnings", "true",
    ]
    res = subprocess.run(cmd, capture_output=True, text=True, env=_sumo_env())
    if res.returncode != 0 or not os.path.isfile(net):
        raise RuntimeError(f"netconvert failed (rc={res.returncode}): {res.stderr.strip()[-2000:]}")
    return net


# --- measurement -------------------------------------------------------------------------
def _measure_in_process(steps: int, vehicles: int, seed: int, warmup_steps: int) -> dict:
    import libsumo

    if vehicles < 1:
        raise ValueError(f"vehicles: {vehicles} is not allowed (need >= 1)")
    if steps < 1 or warmup_steps < 0:
        raise ValueError(f"steps={steps}, warmup_steps={warmup_steps}: need steps >= 1, warmup_steps >= 0")

    with tempfile.TemporaryDirectory(prefix="evoscen_sumo_") as workdir:
        net = _write_network(workdir)
        os.environ.setdefault("SUMO_HOME", _sumo_env().get("SUMO_HOME", ""))
        libsumo.start([
            "sumo",
            "--net-file", net,
            "--step-length", f"{STEP_LENGTH_S}",
            "--seed", str(int(seed)),
            "--no-step-log", "true",
            "--no-warnings", "true",
            "--duration-log.disable", "true",
            "--time-to-teleport", "-1",
            "--collision.action", "warn",
            "--default.action-step-length", f"{STEP_LENGTH_S}",
        ])
        try:
            version = libsumo.getVersion()[1]
            libsumo.route.add(ROUTE_MAIN, ["up", "acc", "down"])
            libsumo.route.add(ROUTE_RAMP, ["ramp", "acc", "down"])
            libsumo.route.add("r_acc", ["acc", "down"])
            libsumo.route.add("r_down", ["down"])

            # initial placement: background vehicles evenly over the mainline, lanes cycled
            n_bg = vehicles - 1
            route_of: dict[str, str] = {}
            usable = ROAD_LENGTH_M - 150.0
            for k in range(n_bg):
                vid = f"bv{k}"
                s = 20.0 + k * usable / max(n_bg, 1)
                lane = k % MAIN_LANES  # evoscen index lane+1
                if s < MERGE_START_M:
                    r, pos, sumo_lane = ROUTE_MAIN, s, lane
                elif s < MERGE_END_M:
                    r, pos, sumo_lane = "r_acc", s - MERGE_START_M, lane + 1
                else:
                    r, pos, sumo_lane = "r_down", s - MERGE_END_M, lane
                libsumo.vehicle.add(vid, r, depart="now", departLane=str(sumo_lane),
                                    departPos=f"{pos:.2f}", departSpeed="max")
                route_of[vid] = ROUTE_MAIN
            libsumo.vehicle.add(SUT_ID, ROUTE_RAMP, depart="now", departLane="0",
                                departPos="base", departSpeed="max")
            route_of[SUT_ID] = ROUTE_RAMP

            step = libsumo.simulationStep
            arrived_ids = libsumo.simulation.getArrivedIDList
            count = libsumo.vehicle.getIDCount
            add = libsumo.vehicle.add
            perf = time.perf_counter

            def reinsert() -> None:
                for vid in arrived_ids():
                    add(vid, route_of[vid], depart="now", departLane="best",
                        departPos="base", departSpeed="max")

            step()  # inserts the initial vehicles
            for _ in range(warmup_steps):
                step()
                reinsert()

            step_time = 0.0
            veh_sum = 0
            loop_t0 = perf()
            for _ in range(steps):
                t0 = perf()
                step()
                step_time += perf() - t0
                veh_sum += count()
                reinsert()
            loop_time = perf() - loop_t0
        finally:
            libsumo.close()

    return {
        "steps_per_s": steps / step_time if step_time > 0 else float("inf"),
        "steps": int(steps),
        "mean_vehicles": veh_sum / steps,
        "sumo_version": version,
        "loop_steps_per_s": steps / loop_time if loop_time > 0 else float("inf"),
        "step_length_s": STEP_LENGTH_S,
        "realtime_factor": (steps * STEP_LENGTH_S) / step_time if step_time > 0 else float("inf"),
    }


def measure_sumo_steps_per_second(steps: int = 3000, vehicles: int = 21, seed: int = 0,
                                  warmup_steps: int = 200, in_process: bool = False) -> dict:
    """Measure SUMO's stepping rate on the evoscen merge scenario (see the module docstring).

    Returns {"steps_per_s", "steps", "mean_vehicles", "sumo_version"} plus the extra keys
    "loop_steps_per_s", "step_length_s", "realtime_factor". Raises RuntimeError when SUMO is
    not available or the run fails. By default runs in a fresh child process (libsumo is a
    per-process singleton); ``in_process=True`` runs in this process.
    """
    ok, why = sumo_available()
    if not ok:
        raise RuntimeError(f"SUMO not available: {why}")
    if in_process:
        return _measure_in_process(steps, vehicles, seed, warmup_steps)
    cmd = [sys.executable, "-c", CHILD, str(int(steps)), str(int(vehicles)), str(int(seed)), str(int(warmup_steps))]
    env = _sumo_env()  # the child imports this module as this process does: its import path passed on
    env["PYTHONPATH"] = os.pathsep.join(p for p in [*sys.path, env.get("PYTHONPATH", "")] if p)
    res = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if res.returncode != 0:
        raise RuntimeError(f"SUMO measurement failed (rc={res.returncode}): {res.stderr.strip()[-2000:]}")
    for line in reversed(res.stdout.strip().splitlines()):
        line = line.strip()
        if line.startswith("{"):
            return json.loads(line)
    raise RuntimeError(f"SUMO measurement printed no result: {res.stdout.strip()[-2000:]}")


def run(steps: int, vehicles: int, seed: int, warmup_steps: int, as_json: bool, in_process: bool) -> None:
    """``scripts/sumo_baseline.py``: one measurement, printed as text or (``as_json``) one JSON line; SUMO
    missing or a failed run is a one-line InputError."""
    from evoscen_sim.errors import InputError

    ok, why = sumo_available()
    if not ok:
        raise InputError(f"SUMO not available: {why}")
    try:
        if in_process:
            r = _measure_in_process(steps, vehicles, seed, warmup_steps)
        else:
            r = measure_sumo_steps_per_second(steps, vehicles, seed, warmup_steps)
    except (RuntimeError, ValueError) as exc:
        raise InputError(str(exc)) from exc
    if as_json:
        print(json.dumps(r))
        return
    print(f"SUMO version     : {r['sumo_version']}")
    print(f"timed steps      : {r['steps']} (dt = {r['step_length_s']} s, after {warmup_steps} warm-up)")
    print(f"steps/s          : {r['steps_per_s']:.1f}  (simulationStep only)")
    print(f"steps/s (loop)   : {r['loop_steps_per_s']:.1f}  (incl. counting + re-insertion)")
    print(f"real-time factor : {r['realtime_factor']:.1f}x")
    print(f"mean vehicles    : {r['mean_vehicles']:.2f}")
