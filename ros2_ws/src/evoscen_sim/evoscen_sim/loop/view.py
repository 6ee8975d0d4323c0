"""What a driver sees: the traffic at one step, in the simulator or rebuilt from the wire.

Driver models (level-0, learned BVs, SUT models) decide from a *traffic view*: any object
with the attributes below. :class:`evoscen_sim.physics.world.World` is one (in-process runs);
:class:`WorldView` is the other, rebuilt from a ``/evoscen/world`` table by the BV and SUT
nodes. Both compute road look-ups and neighbourhoods with the same code from the same
numbers, so a driver decides identically in either runner.

Attributes a driver may use (arrays over vehicles, index = row of the world table):
``n``, ``ids``, ``role``, ``policy``, ``s``, ``d``, ``psi`` (heading relative to the road),
``v``, ``accel``, ``steer``, ``lane``, ``target_lane``, ``lane_change``, ``length``,
``width``, ``speed_limit_mps``; methods ``neighborhood()``; and ``road``, ``dt_s``,
``time_s``, ``step_index``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Protocol

import numpy as np

from evoscen_sim.physics.neighbors import Neighborhood, compute_neighborhood


class TrafficView(Protocol):
    """The attributes of a traffic view (see the module docstring)."""

    n: int
    ids: np.ndarray
    role: np.ndarray
    policy: np.ndarray
    s: np.ndarray
    d: np.ndarray
    psi: np.ndarray
    v: np.ndarray
    accel: np.ndarray
    steer: np.ndarray
    lane: np.ndarray
    target_lane: np.ndarray
    lane_change: np.ndarray
    length: np.ndarray
    width: np.ndarray
    road: object
    dt_s: float
    step_index: int

    @property
    def time_s(self) -> float: ...  # pragma: no cover - protocol

    @property
    def speed_limit_mps(self) -> np.ndarray: ...  # pragma: no cover - protocol

    def neighborhood(self) -> Neighborhood: ...  # pragma: no cover - protocol

    def lane_lookup(self): ...  # pragma: no cover - protocol


_INT_COLUMNS = ("id", "role", "policy", "lane", "target_lane", "lane_change")


class WorldView:
    """A traffic view rebuilt from the columns of a world table (``/evoscen/world``).

    Args:
        road: the scenario's :class:`evoscen_sim.road.road_model.RoadModel`.
        columns: the world table's columns (``evoscen_contract.tables.table_columns``).
        step_index: the step ``k`` of the table (its stamp is ``k * dt_s``).
        dt_s: the scenario's step.
    """

    def __init__(self, road, columns: Mapping[str, np.ndarray], step_index: int, dt_s: float) -> None:
        missing = [c for c in ("id", "role", "policy", "s", "d", "heading_rel", "speed", "accel", "steer", "lane",
                               "target_lane", "lane_change", "length", "width") if c not in columns]
        if missing:
            raise ValueError(f"world table: missing columns {missing}")
        ints = {c: np.asarray(columns[c]).astype(np.int64) for c in _INT_COLUMNS}
        floats = {c: np.ascontiguousarray(columns[c], dtype=float) for c in columns if c not in _INT_COLUMNS}
        self.road = road
        self.dt_s = float(dt_s)
        self.step_index = int(step_index)
        self.ids = ints["id"]
        self.role = ints["role"]
        self.policy = ints["policy"]
        self.lane = ints["lane"]
        self.target_lane = ints["target_lane"]
        self.lane_change = ints["lane_change"]
        self.s = floats["s"]
        self.d = floats["d"]
        self.psi = floats["heading_rel"]
        self.v = floats["speed"]
        self.accel = floats["accel"]
        self.steer = floats["steer"]
        self.length = floats["length"]
        self.width = floats["width"]
        self.n = int(self.s.shape[0])
        self._neighborhood: Neighborhood | None = None
        self._speed_limit: np.ndarray | None = None
        self._lanes = None

    def lane_lookup(self):  # evoscen_sim.road.road_model.LaneLookup
        """Lane data (borders, existence, limits) at every vehicle's position (cached)."""
        if self._lanes is None:
            self._lanes = self.road.lane_lookup(np.maximum(self.s, 0.0), self.d)
        return self._lanes

    @property
    def time_s(self) -> float:
        """Simulation time of the view (s)."""
        return self.step_index * self.dt_s

    @property
    def speed_limit_mps(self) -> np.ndarray:
        """Maximum speed of every vehicle's lane at its position (m/s)."""
        if self._speed_limit is None:
            self._speed_limit = self.lane_lookup().max_speed_mps[np.arange(self.n), self.lane]
        return self._speed_limit

    def neighborhood(self) -> Neighborhood:
        """Leaders and followers of every vehicle (cached)."""
        if self._neighborhood is None:
            self._neighborhood = compute_neighborhood(self.s, self.lane, self.v, self.accel, self.length)
        return self._neighborhood
