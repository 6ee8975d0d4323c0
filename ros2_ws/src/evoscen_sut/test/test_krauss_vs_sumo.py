"""evoscen_sut.krauss against SUMO itself (libsumo): the same leader, the same follower trajectory.

Scenario (SUMO, ``--step-length 0.1``, Euler update, one straight 1-lane edge of 3 km at
33.33 m/s): a leader driven by ``vehicle.setSpeed`` (speed mode 0: the profile is followed
exactly) and a Krauss follower with SUMO's default vType parameters except ``sigma = 0``
(deterministic), ``length = 4.8`` (our vehicles) and ``speedDev = 0`` (speedFactor exactly 1).
A third, separate vehicle (σ = 0.5) on its own edge checks the free-road dawdling law; a fourth
(σ = 0) on a third edge sees its lane limit drop from 33.33 to 20 m/s at t = 20 s.
Leader profile: 25 m/s; braking at 6 m/s² (harder than the follower's decel 4.5: the
emergency branch) to 7 m/s; +2 m/s² to 23 m/s; braking at 8 m/s² to a standstill (the
follower stops behind it and creeps to ``minGap``); +2 m/s² to 30 m/s.

Comparison (the model itself, not the bicycle world): the leader's recorded SUMO positions and
speeds are replayed; our follower starts from SUMO's follower state once both are on the road
and is integrated with SUMO's Euler update (``v ← krauss_next_speed(...)``,
``s_front ← s_front + v Δt``), its gap = leader's front − leader length − own front.

Tolerance: max |Δv| < 1e-6 m/s over the 80 s (and |Δs| < 1e-5 m). Both sides compute the same
formulas in IEEE double precision, so the only expected differences are rounding-order effects
(~1e-12); a tolerance of 1e-6 still catches any change of a branch (one wrong step of an
emergency or dawdling branch moves the speed by ≥ 0.01 m/s), and is far below
0.05 m/s.

SUMO is optional: the test is skipped when libsumo cannot be imported or netconvert is not
found (``pip install eclipse-sumo libsumo``; tested with 1.28.0).
"""

from __future__ import annotations

import os
import subprocess

import numpy as np
import pytest

libsumo = pytest.importorskip("libsumo", reason="SUMO comparison needs libsumo (pip install eclipse-sumo libsumo)")

from evoscen_sut.krauss import KraussParams, krauss_next_speed  # noqa: E402 (after the importorskip)

DT = 0.1
LENGTH = 4.8
SPEED_LIMIT = 33.33
EDGE_LENGTH = 12000.0
DURATION_S = 80.0
FREE_DURATION_S = 300.0
LIMIT_DROP_S = 20.0
LOW_LIMIT = 20.0
PARAMS = KraussParams(sigma=0.0, desired_speed_mps=SPEED_LIMIT)
FREE_PARAMS = KraussParams(desired_speed_mps=SPEED_LIMIT)  # SUMO defaults, sigma 0.5


def _sumo_baseline():
    """The repository's SUMO discovery (evoscen_experiments.sumo_baseline), shared with the benchmark."""
    from evoscen_experiments import sumo_baseline

    return sumo_baseline


def _sumo_home() -> str | None:
    return _sumo_baseline()._sumo_home()


def _netconvert() -> str | None:
    return _sumo_baseline()._find_netconvert()


def leader_speed_profile(t: float) -> float:
    """The leader's commanded speed (m/s) at time ``t`` (s)."""
    if t < 10.0:
        return 25.0
    if t < 20.0:
        return max(7.0, 25.0 - 6.0 * (t - 10.0))
    if t < 40.0:
        return min(23.0, 7.0 + 2.0 * (t - 20.0))
    if t < 55.0:
        return max(0.0, 23.0 - 8.0 * (t - 40.0))
    return min(30.0, 2.0 * (t - 55.0))


def _run_sumo(workdir: str) -> dict[str, np.ndarray]:
    netconvert = _netconvert()
    if netconvert is None:
        pytest.skip("SUMO comparison needs netconvert (eclipse-sumo package, SUMO_HOME/bin or PATH)")
    home = _sumo_home()
    env = dict(os.environ)
    if home:
        env["SUMO_HOME"] = home
        os.environ.setdefault("SUMO_HOME", home)
    with open(os.path.join(workdir, "n.nod.xml"), "w") as f:
        f.write(f'<nodes><node id="a" x="0" y="0"/><node id="b" x="{EDGE_LENGTH}" y="0"/>'
                f'<node id="c" x="0" y="100"/><node id="d" x="{EDGE_LENGTH}" y="100"/>'
                f'<node id="g0" x="0" y="200"/><node id="g1" x="{EDGE_LENGTH}" y="200"/></nodes>\n')
    with open(os.path.join(workdir, "n.edg.xml"), "w") as f:
        f.write(f'<edges><edge id="e" from="a" to="b" numLanes="1" speed="{SPEED_LIMIT}"/>'
                f'<edge id="f" from="c" to="d" numLanes="1" speed="{SPEED_LIMIT}"/>'
                f'<edge id="g" from="g0" to="g1" numLanes="1" speed="{SPEED_LIMIT}"/></edges>\n')
    net = os.path.join(workdir, "n.net.xml")
    res = subprocess.run([netconvert, "--node-files", os.path.join(workdir, "n.nod.xml"),
                          "--edge-files", os.path.join(workdir, "n.edg.xml"), "--output-file", net,
                          "--no-warnings", "true"], check=False, capture_output=True, text=True, env=env)
    if res.returncode != 0:
        pytest.skip(f"netconvert failed (rc={res.returncode}): {res.stderr.strip()[-500:]}")
    rou = os.path.join(workdir, "r.rou.xml")
    with open(rou, "w") as f:
        f.write(
            "<routes>\n"
            + "".join(
                f'  <vType id="{name}" carFollowModel="Krauss" accel="{p.accel_mps2}" decel="{p.decel_mps2}"'
                f' emergencyDecel="{p.emergency_decel_mps2}" sigma="{p.sigma}" tau="{p.tau_s}"'
                f' minGap="{p.min_gap_m}" length="{LENGTH}" speedFactor="1" speedDev="0" maxSpeed="55.55"/>\n'
                for name, p in (("krauss", PARAMS), ("krauss_sigma", FREE_PARAMS)))
            + '  <route id="r" edges="e"/>\n'
            '  <route id="rf" edges="f"/>\n'
            '  <route id="rg" edges="g"/>\n'
            '  <vehicle id="leader" type="krauss" route="r" depart="0" departPos="100" departSpeed="25"/>\n'
            '  <vehicle id="follower" type="krauss" route="r" depart="0" departPos="40" departSpeed="25"/>\n'
            f'  <vehicle id="free" type="krauss_sigma" route="rf" depart="0" departPos="0" departSpeed="{SPEED_LIMIT}"/>\n'
            '  <vehicle id="limit" type="krauss" route="rg" depart="0" departPos="0" departSpeed="30"/>\n'
            "</routes>\n"
        )
    libsumo.start(["sumo", "-n", net, "-r", rou, "--step-length", f"{DT}", "--no-step-log", "true",
                   "--no-warnings", "true", "--duration-log.disable", "true", "--time-to-teleport", "-1",
                   "--collision.action", "warn", "--seed", "1"])
    try:
        steps = round(DURATION_S / DT)
        rec = {k: np.full(steps, np.nan) for k in ("xl", "vl", "xf", "vf")}
        rec["v_free"] = np.full(round(FREE_DURATION_S / DT), np.nan)
        rec["v_limit"] = np.full(steps, np.nan)
        rec["limit"] = np.full(steps, SPEED_LIMIT)  # lane g's limit during step k (after record k - 1)
        libsumo.simulationStep()
        libsumo.vehicle.setSpeedMode("leader", 0)
        for k in range(rec["v_free"].shape[0]):
            t = libsumo.simulation.getTime()
            libsumo.vehicle.setSpeed("leader", leader_speed_profile(t))
            if k < steps and t >= LIMIT_DROP_S:
                libsumo.lane.setMaxSpeed("g_0", LOW_LIMIT)
                rec["limit"][k] = LOW_LIMIT
            libsumo.simulationStep()
            if k < steps:
                rec["v_limit"][k] = libsumo.vehicle.getSpeed("limit")
            ids = set(libsumo.vehicle.getIDList())
            if "free" in ids:
                rec["v_free"][k] = libsumo.vehicle.getSpeed("free")
            if k < steps and {"leader", "follower"} <= ids:
                rec["xl"][k] = libsumo.vehicle.getLanePosition("leader")
                rec["vl"][k] = libsumo.vehicle.getSpeed("leader")
                rec["xf"][k] = libsumo.vehicle.getLanePosition("follower")
                rec["vf"][k] = libsumo.vehicle.getSpeed("follower")
    finally:
        libsumo.close()
    return rec


def _replay(rec: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Our follower on SUMO's leader trajectory, from SUMO's first follower state."""
    xl, vl = rec["xl"], rec["vl"]
    n = xl.shape[0]
    xf = np.full(n, np.nan)
    vf = np.full(n, np.nan)
    xf[0], vf[0] = rec["xf"][0], rec["vf"][0]
    for k in range(n - 1):
        gap = xl[k] - LENGTH - xf[k]
        vf[k + 1] = krauss_next_speed(vf[k], SPEED_LIMIT, gap, vl[k], 0.0, PARAMS, DT)
        xf[k + 1] = xf[k] + vf[k + 1] * DT
    return xf, vf


@pytest.fixture(scope="module")
def trajectories(tmp_path_factory) -> dict[str, np.ndarray]:
    rec = _run_sumo(str(tmp_path_factory.mktemp("sumo_krauss")))
    assert np.all(np.isfinite(rec["vf"])), "both vehicles must stay on the road for the whole run"
    assert np.all(np.isfinite(rec["v_free"])), "the free vehicle must stay on the road for the whole run"
    xf, vf = _replay(rec)
    return {**rec, "xf_ours": xf, "vf_ours": vf}


def test_scenario_exercises_the_model(trajectories) -> None:
    """The run covers following, emergency braking (> decel), a standstill behind the leader and free acceleration."""
    vf = trajectories["vf"]
    decel = -np.diff(vf) / DT
    assert decel.max() > PARAMS.decel_mps2 + 0.5  # the emergency branch was taken
    assert vf.min() < 0.05  # the follower (nearly) stopped
    gap = trajectories["xl"] - LENGTH - trajectories["xf"]
    assert gap.min() > 0.0  # no collision in SUMO either
    assert np.diff(vf).max() == pytest.approx(PARAMS.accel_mps2 * DT, abs=1e-9)  # full acceleration used


def test_follower_speed_matches_sumo(trajectories) -> None:
    dv = np.abs(trajectories["vf_ours"] - trajectories["vf"])
    ds = np.abs(trajectories["xf_ours"] - trajectories["xf"])
    worst = int(np.argmax(dv))
    assert dv.max() < 1e-6, f"max |dv| = {dv.max():.3g} m/s at t = {(worst + 1) * DT:.1f} s"
    assert ds.max() < 1e-5, f"max |ds| = {ds.max():.3g} m"


def test_free_road_dawdling_mean_in_sumo(trajectories) -> None:
    """SUMO's own free-road speeds (sigma 0.5) follow the law derived in evoscen_sut.krauss.

    v_next = v_max − σ a Δt U: uniform on (v_max − σ a Δt, v_max], mean v_max − σ a Δt / 2 = 33.265 m/s,
    standard deviation σ a Δt / √12 = 0.0375 m/s, i.e. 0.0007 m/s for the mean of 2999 steps: tolerance 0.004 m/s.
    """
    p = FREE_PARAMS
    v = trajectories["v_free"][1:]
    width = p.sigma * p.accel_mps2 * DT
    assert v.max() <= SPEED_LIMIT + 1e-9
    assert v.min() >= SPEED_LIMIT - width - 1e-9
    assert v.mean() == pytest.approx(SPEED_LIMIT - width / 2.0, abs=0.004)
    assert v.std() == pytest.approx(width / np.sqrt(12.0), abs=0.004)


def test_speed_limit_drop_matches_sumo(trajectories) -> None:
    """A lane limit dropping from 33.33 to 20 m/s at t = 20 s: SUMO slows at decel (4.5 m/s²), not emergencyDecel.

    (MSVehicle::planMoveInternal: "speed limits are not emergencies".) Same replay, max |Δv| < 1e-6 m/s.
    """
    v_sumo = trajectories["v_limit"]
    limit = trajectories["limit"]
    v = np.empty_like(v_sumo)
    v[0] = v_sumo[0]
    for k in range(v.shape[0] - 1):
        v[k + 1] = krauss_next_speed(v[k], limit[k + 1], np.inf, np.nan, 0.0, PARAMS, DT)
    assert np.abs(v - v_sumo).max() < 1e-6
    decel = -np.diff(v_sumo) / DT
    assert decel.max() == pytest.approx(PARAMS.decel_mps2, abs=1e-9)
    assert v_sumo[-1] == pytest.approx(LOW_LIMIT, abs=1e-9)
