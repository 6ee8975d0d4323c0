"""The simulation's per-step messages as CDR bytes, built the same way in every runner.

The in-process runner records these bytes; the simulation node publishes them
(``publisher.publish(bytes)``). Tables, ``/clock``, the SUT's odometry, the vehicle markers,
the events and the (once-published) map markers are canonical CDR from :mod:`evoscen_contract.cdr`.
"""

from __future__ import annotations

import operator
from collections.abc import Mapping, Sequence

import numpy as np

from . import topics as T
from .cdr import EmptyEventsEncoder, OdometryEncoder, TableEncoder, clock_parts, encode_clock, encode_event_statuses
from .cdr_markers import VehicleMarkersEncoder, encode_road_markers


class WorldMessages:
    """Encoders for the world-side topics of the contract (one instance per run)."""

    def __init__(self, dt_s: float) -> None:
        self.dt_s = dt_s
        self._world = TableEncoder(T.WORLD_FIELDS, T.MAP_FRAME)
        self._roster = TableEncoder(T.ROSTER_FIELDS, T.MAP_FRAME)
        self._commands = TableEncoder(T.COMMAND_FIELDS, T.MAP_FRAME)
        self._odometry = OdometryEncoder(T.MAP_FRAME, T.SUT_BASE_FRAME)
        self._no_events = EmptyEventsEncoder(T.MAP_FRAME)
        self._markers = VehicleMarkersEncoder(T.MAP_FRAME)
        self._prev_yaw: float | None = None
        self._world_columns = operator.itemgetter(*T.WORLD_FIELDS)  # the world table's columns, in order

    @staticmethod
    def clock(t_ns: int) -> bytes:
        """``/clock`` at ``t_ns``."""
        return encode_clock(t_ns)

    def world(self, columns: Mapping[str, np.ndarray], t_ns: int) -> bytes:
        """``/evoscen/world`` from the world's columns."""
        return self._world.encode_columns(self._world_columns(columns), t_ns)

    def world_parts(self, columns: Mapping[str, np.ndarray], t_ns: int) -> tuple[bytes, ...]:
        """:meth:`world`'s bytes in pieces (their join)."""
        return self._world.parts_columns(self._world_columns(columns), t_ns)

    def roster(self, columns: Mapping[str, np.ndarray], t_ns: int) -> bytes:
        """``/evoscen/roster`` from the world's columns."""
        return self._roster.encode_columns([columns[f] for f in T.ROSTER_FIELDS], t_ns)

    def odometry(self, columns: Mapping[str, np.ndarray], sut_index: int, t_ns: int) -> bytes:
        """``/evoscen/sut/odom``; the yaw rate is the yaw change since the previous call / dt."""
        yaw = float(columns["yaw"][sut_index])
        yaw_rate = 0.0 if self._prev_yaw is None else (yaw - self._prev_yaw) / self.dt_s
        self._prev_yaw = yaw
        return self._odometry.encode(columns["x"][sut_index], columns["y"][sut_index], yaw,
                                     columns["speed"][sut_index], yaw_rate, t_ns)

    def odometry_parts(self, columns: Mapping[str, np.ndarray], sut_index: int, t_ns: int) -> tuple[bytes, ...]:
        """:meth:`odometry`'s bytes in pieces (their join); the same yaw-rate bookkeeping."""
        yaw = float(columns["yaw"][sut_index])
        yaw_rate = 0.0 if self._prev_yaw is None else (yaw - self._prev_yaw) / self.dt_s
        self._prev_yaw = yaw
        return self._odometry.parts(columns["x"][sut_index], columns["y"][sut_index], yaw,
                                    columns["speed"][sut_index], yaw_rate, t_ns)

    def commands_parts(self, ids: np.ndarray, throttle: np.ndarray, lane_change: np.ndarray,
                       t_ns: int) -> tuple[bytes, ...]:
        """:meth:`commands`'s bytes in pieces (their join)."""
        return self._commands.parts_columns((ids, throttle, lane_change), t_ns)

    @staticmethod
    def clock_parts(t_ns: int) -> tuple[bytes, ...]:
        """:meth:`clock`'s bytes in pieces (their join)."""
        return clock_parts(t_ns)

    def commands(self, ids: np.ndarray, throttle: np.ndarray, lane_change: np.ndarray, t_ns: int) -> bytes:
        """A command table (``/evoscen/commands/bv`` or ``/sut``) answering the world at ``t_ns``."""
        return self._commands.encode_columns((ids, throttle, lane_change), t_ns)

    def vehicle_markers(self, columns: Mapping[str, np.ndarray], t_ns: int) -> bytes:
        """``/evoscen/markers`` (canonical CDR)."""
        return self._markers.encode(columns, t_ns)

    @staticmethod
    def map_markers(road, t_ns: int) -> bytes:
        """``/evoscen/map_markers`` of ``road`` (canonical CDR, :func:`~evoscen_contract.cdr_markers.encode_road_markers`)."""
        return encode_road_markers(road, t_ns)

    def events(self, events: Sequence[Mapping], t_ns: int) -> bytes:
        """``/evoscen/events`` (canonical CDR; a step without events from a template)."""
        if not events:
            return self._no_events.encode(t_ns)
        return encode_event_statuses(T.event_statuses(events), t_ns)
