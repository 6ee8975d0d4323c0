"""The background traffic's make-up (``bvs.makeup``; docs/bv-profiles.md, "Traffic make-up").

* ``uniform``: every BV is a car of the ``vehicle`` section's length and width, its desired
  speed the driver's own draw capped at the lane's limit (the traffic before make-ups existed, bag
  for bag; the default before 0.7.0).
* ``highd`` (default): each BV slot is a car or a truck, with a length, a width and a desired speed drawn from
  the per-class figures of the highD dataset's recordings with a 120 km/h limit (R. Krajewski, J. Bock,
  L. Kloeker, L. Eckstein, *The highD Dataset*, IEEE ITSC 2018): :class:`HighdMakeupParams`, the
  parameter set ``models.highd``.

The draws (:func:`draw_makeup`) come from the scenario's own ``makeup`` stream
(:func:`evoscen_sim.scenario_builders.scenario_rngs`), made once per slot for the whole run — the
simulation node (lengths, widths, entry speeds) and every BV node (which driver, desired speeds)
draw the same, so the world does not depend on how the BVs are split over nodes. A slot keeps its
class when it re-enters the window (docs/architecture.md §5: a vehicle keeps its id and driver).

[choice] The class travels in the world table as the vehicle's length: a vehicle longer than
:data:`TRUCK_MIN_LENGTH_M` is a truck (highD's trucks: p5 7.1 m; its cars: p95 6.2 m), so the wire
format needs no new column.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from evoscen_contract.contract import TRUCK_MIN_LENGTH_M  # a vehicle longer is a truck (m)

from evoscen_sim.config.config_checks import flag, integer, number, text
from evoscen_sim.config.config_schema import MAKEUPS  # noqa: F401  (the values of ``bvs.makeup``)



def shipped_policy_set(makeup: str) -> str:
    """The learned BVs' policy set that ``models.learned.policy_dir: shipped`` names under ``makeup``.
    [choice] ``highd_trained`` under ``highd`` (the set trained in the traffic it drives in; its cars'
    lane-change rate nearest highD's, docs/learned-bvs.md), ``v0.6.0`` under ``uniform`` (its bags
    unchanged). :func:`evoscen_bv.bv_models.shipped_set` finds the directory; the report names the set."""
    return "highd_trained" if makeup == HIGHD else "v0.6.0"

HIGHD = "highd"


@dataclass(frozen=True)
class HighdMakeupParams:
    """The ``highd`` make-up (scenario YAML ``models.highd``). Defaults: highD, 120 km/h recordings
    (Krajewski et al., ITSC 2018; lengths over all recordings, the only ones aggregated)."""

    truck_share: float = number(0.229, 0.0, 1.0)
    """Share of trucks among the BV slots, the density share. [choice] 0.229: highD counts vehicles
    passing its section, 18.86 % trucks at 120 km/h — a share of the flow; on the road (a share of the
    density) the slower trucks are more: 0.1886/23.84 / (0.1886/23.84 + 0.8114/30.38) = 0.229 with
    highD's per-class mean speeds."""
    car_length_p5_m: float = number(3.94, 1.0, 7.0)
    """Car length, 5th percentile (m): highD 3.94."""
    car_length_p50_m: float = number(4.75, 1.0, 7.0)
    """Car length, median (m): highD 4.75."""
    car_length_p95_m: float = number(6.16, 1.0, 7.0)
    """Car length, 95th percentile (m): highD 6.16 (a draw is kept at most 6.9 m: below the truck class)."""
    truck_length_p5_m: float = number(7.1, 7.0, 30.0, lo_open=True)
    """Truck length, 5th percentile (m): highD 7.07 (draws are kept at least this long)."""
    truck_length_p50_m: float = number(16.7, 7.0, 30.0, lo_open=True)
    """Truck length, median (m): highD 16.67."""
    truck_length_p95_m: float = number(19.5, 7.0, 30.0, lo_open=True)
    """Truck length, 95th percentile (m): highD 19.5."""
    truck_width_m: float = number(2.5, 1.0, 3.0)
    """Truck width (m): the 2.55 m EU maximum (Directive 96/53/EC), rounded. Cars keep ``vehicle.width_m``."""
    car_speed_p5_mps: float = number(22.0, 0.0, 40.0, lo_open=True)
    """Car desired speed, 5th percentile (m/s). [choice] 22.0, calibrated: highD's per-car mean speed p5 is
    20.93, but that lower tail (a mean below the median) holds congestion, not only drivers' wishes, and
    the simulated traffic hinders on its own; with 20.93 the simulated pieces' mean speed fell 2.7 m/s
    below highD's, with the upper half mirrored (25.39) their sd to 4.3 m/s (docs/bv-profiles.md)."""
    car_speed_p50_mps: float = number(31.45, 0.0, 40.0, lo_open=True)
    """Car desired speed, median (m/s): highD 31.45."""
    car_speed_p95_mps: float = number(37.51, 0.0, 40.0, lo_open=True)
    """Car desired speed, 95th percentile (m/s): highD 37.51 (real drivers exceed the 33.3 m/s limit)."""
    truck_speed_p5_mps: float = number(21.74, 0.0, 40.0, lo_open=True)
    """Truck desired speed, 5th percentile (m/s). [choice] 21.74 = p50 − (p95 − p50), mirrored as the cars'
    (highD's per-truck mean speed p5: 20.43)."""
    truck_speed_p50_mps: float = number(24.13, 0.0, 40.0, lo_open=True)
    """Truck desired speed, median (m/s): highD 24.13."""
    truck_speed_p95_mps: float = number(26.52, 0.0, 40.0, lo_open=True)
    """Truck desired speed, 95th percentile (m/s): highD 26.52."""
    truck_entry_lanes: int = integer(1, 1, 8)
    """Trucks enter the traffic window on the rightmost this-many mainline lanes (highD: trucks keep right).
    [choice] 1, lane II: with 2, trucks entering in lane III changed to lane II soon after, most of their
    lane changes (traffic_makeup.py)."""
    car_lanes: str = text("by_speed", ("by_speed", "by_density"))
    """Which mainline lane a car starts or enters in. ``by_speed``: at the start, the slowest cars take
    the rightmost slots left by the trucks and the fastest the leftmost; on entry, of the lanes below
    their target density, the one whose traffic in the window moves nearest the car's desired speed
    (its ``traffic.lane_speed_mps`` mean while it is empty). ``by_density``: the lane furthest below
    its target, whatever the car's speed (the make-up's first form). [choice] by_speed: highD's lanes
    are sorted by speed (drivers keep right unless overtaking), and with ``by_density`` fast cars
    entered behind slow ones and spent 42 % of their time held up below their desired speed
    (docs/bv-profiles.md, "Where the cars' speed goes")."""
    front_entry_speed: str = text("raise", ("raise", "wish"))
    """The speed of a vehicle entering at the window's front edge (slower than the SUT: traffic it will catch
    up with). ``wish``: its desired speed, lowered if its leader needs it (the make-up's first form); where
    the vehicle behind could not follow it safely, it does not enter and tries again later. ``raise``: in
    that case, the lowest speed the vehicle behind can follow (safe-insertion rule), if at most the SUT's
    speed and what its leader allows; it then slows to its wish as its driver does. [choice] raise: the
    mirror of the rear edge's rule, which lowers an entry's speed for its leader. Under ``wish`` a truck
    (lane II only, ~22 m/s) needs ~100 m behind it of a car at 32 m/s; with lane II full of faster cars and
    the SUT, trucks spent 61 % of their time outside the window on 2 of 6 seeds and the SUT's
    surroundings thinned to 3.8 BVs within ±100 m in a 30-s window (docs/bv-profiles.md, "Entries at the
    front edge")."""
    truck_ramp_entries: bool = flag(False)
    """Whether trucks also enter on the merge lane. [choice] false: the truck driver has no gap-seeking
    merge (the learned cars' ``merge_seek``), and trucks that entered there stopped near its end and
    merged at 6–9 m/s into lane II's 20-m/s traffic (traced in the runs)."""


@dataclass(frozen=True)
class Makeup:
    """One draw of :func:`draw_makeup`: per BV slot (position k = world index k + 1)."""

    truck: np.ndarray
    """bool: the slot is a truck."""
    length_m: np.ndarray
    width_m: np.ndarray
    desired_speed_mps: np.ndarray


def quantile_curve(p5: float, p50: float, p95: float) -> tuple[np.ndarray, np.ndarray]:
    """Knots ``(u, x)`` of the piecewise-linear inverse CDF through the three percentiles, each end
    segment continued with its neighbour's slope to u = 0 and u = 1 ([choice]: no tails known)."""
    lo = p5 - (p50 - p5) * (0.05 / 0.45)
    hi = p95 + (p95 - p50) * (0.05 / 0.45)
    return np.array([0.0, 0.05, 0.5, 0.95, 1.0]), np.array([lo, p5, p50, p95, hi])


def from_quantiles(u: np.ndarray, p5: float, p50: float, p95: float) -> np.ndarray:
    """Values at uniform draws ``u`` of the distribution :func:`quantile_curve` describes."""
    knots_u, knots_x = quantile_curve(p5, p50, p95)
    return np.interp(u, knots_u, knots_x)


def draw_makeup(n: int, p: HighdMakeupParams, car_width_m: float, rng: np.random.Generator) -> Makeup:
    """Classes, lengths, widths and desired speeds of ``n`` BV slots (module docstring).

    [choice] The number of trucks is ``floor(n·share)`` plus one with probability equal to the
    remainder (expected ``n·share`` exactly, never further than one from it), placed on a random
    permutation of the slots; lengths and speeds are quantile-interpolated (:func:`from_quantiles`).
    Draws, always in this order and number: one ``random``, one ``permutation(n)``, ``n`` uniforms
    for the lengths, ``n`` for the speeds.
    """
    quota = n * float(p.truck_share)
    n_truck = int(np.floor(quota))
    n_truck += int(rng.random() < quota - n_truck)
    n_truck = min(n_truck, n)
    order = rng.permutation(n)
    truck = np.zeros(n, dtype=bool)
    truck[order[:n_truck]] = True
    u_len = rng.random(n)
    u_speed = rng.random(n)
    car_len = np.minimum(from_quantiles(u_len, p.car_length_p5_m, p.car_length_p50_m, p.car_length_p95_m),
                         TRUCK_MIN_LENGTH_M - 0.1)
    truck_len = np.maximum(from_quantiles(u_len, p.truck_length_p5_m, p.truck_length_p50_m, p.truck_length_p95_m),
                           p.truck_length_p5_m)
    car_v = from_quantiles(u_speed, p.car_speed_p5_mps, p.car_speed_p50_mps, p.car_speed_p95_mps)
    truck_v = from_quantiles(u_speed, p.truck_speed_p5_mps, p.truck_speed_p50_mps, p.truck_speed_p95_mps)
    return Makeup(truck=truck, length_m=np.where(truck, truck_len, car_len),
                  width_m=np.where(truck, float(p.truck_width_m), float(car_width_m)),
                  desired_speed_mps=np.maximum(np.where(truck, truck_v, car_v), 0.1))


def is_truck(length_m: np.ndarray) -> np.ndarray:
    """Which vehicles are trucks, from their lengths (the world table's ``length`` column)."""
    return np.asarray(length_m, dtype=float) > TRUCK_MIN_LENGTH_M


@dataclass(frozen=True)
class WindowMakeup:
    """What the traffic window's entries need of a make-up (:class:`evoscen_sim.physics.window.TrafficWindow`),
    per world index (the SUT, index 0, first: no wish, no truck)."""

    wish_mps: np.ndarray
    """Desired speed of each slot: its entry speed before the safe-insertion rule (m/s; NaN: the SUT)."""
    truck: np.ndarray
    """bool: the slot is a truck (enters only the rightmost ``truck_entry_lanes``, and the merge lane with
    ``truck_ramp_entries``)."""
    truck_entry_lanes: int
    truck_ramp_entries: bool = False
    raise_front_entries: bool = False
    """A vehicle entering at the window's front edge may be faster than its wish, up to the SUT's speed, where
    its follower could not follow it at its wish (``front_entry_speed: raise``)."""
    cars_by_speed: bool = False
    """Cars enter the lane whose traffic moves nearest their desired speed (``car_lanes: by_speed``)."""


def window_makeup(m: Makeup, p: HighdMakeupParams) -> WindowMakeup:
    """:class:`WindowMakeup` of the BV slots of ``m`` behind the SUT's row."""
    return WindowMakeup(wish_mps=np.concatenate([[np.nan], m.desired_speed_mps]),
                        truck=np.concatenate([[False], m.truck]), truck_entry_lanes=int(p.truck_entry_lanes),
                        truck_ramp_entries=bool(p.truck_ramp_entries),
                        raise_front_entries=p.front_entry_speed == "raise", cars_by_speed=p.car_lanes == "by_speed")
