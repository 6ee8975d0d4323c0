"""Visualization: ``visualization_msgs/MarkerArray`` of the vehicles and of the road.

* ``/evoscen/markers`` — every vehicle as an oriented box (a ``CUBE`` marker sized to the
  vehicle, 1.5 m high, at its position and heading) coloured by its driver policy (SUT
  distinct; a truck — longer than :data:`~evoscen_contract.contract.TRUCK_MIN_LENGTH_M` — in the truck
  colour whatever its policy code), and a text marker above it with its id and speed (km/h). Published every
  ``recording.markers_every`` steps (building ~40 markers per step in Python is the most
  expensive message of a step, and the bag's largest).
* ``/evoscen/map_markers`` — the road's lane lines and edges (``LINE_LIST`` segments of the
  road model's ~5 m samples: broken lines draw every third segment, solid lines all), published once,
  transient-local, so RViz or Foxglove joining late still gets them.

All in the ``map`` frame; Foxglove's 3D panel and RViz display them as they are.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from .tables import stamp_from_ns
from .contract import MAP_FRAME, POLICY_CODES, TRUCK_MIN_LENGTH_M

VEHICLE_HEIGHT_M = 1.5
POLICY_COLORS: dict[str, tuple[float, float, float]] = {
    "level0": (0.6, 0.6, 0.6),  # grey
    "mutual": (0.2, 0.4, 1.0),  # blue
    "competitive": (0.9, 0.1, 0.1),  # red
    "cooperative": (0.1, 0.75, 0.2),  # green
    "sut": (1.0, 0.75, 0.0),  # amber: the system under test
    "nilsson": (0.6, 0.2, 0.8),  # purple
    "mobil": (0.0, 0.75, 0.8),  # cyan
}
"""Box colour (r, g, b) per policy: competitive red, mutual blue, cooperative green, SUT amber."""
TRUCK_COLOR: tuple[float, float, float] = (0.55, 0.5, 0.15)
"""Box colour of a truck BV (olive), whatever the policy code its slot carries."""
_CODE_COLORS = {POLICY_CODES[name]: rgb for name, rgb in POLICY_COLORS.items()}
CUBE = 1  # visualization_msgs/Marker.CUBE
TEXT_VIEW_FACING = 9  # visualization_msgs/Marker.TEXT_VIEW_FACING


def policy_color(code: float) -> tuple[float, float, float]:
    """Box colour of a policy code (white for an unknown code)."""
    return _CODE_COLORS.get(int(code), (1.0, 1.0, 1.0))


def vehicle_color(code: float, length_m: float) -> tuple[float, float, float]:
    """Box colour of a vehicle: :data:`TRUCK_COLOR` for a BV longer than ``TRUCK_MIN_LENGTH_M``, else
    its policy's (the SUT keeps its colour whatever its length)."""
    if float(length_m) > TRUCK_MIN_LENGTH_M and int(code) != POLICY_CODES["sut"]:
        return TRUCK_COLOR
    return policy_color(code)


def _color(rgb: tuple[float, float, float], alpha: float = 1.0):
    from std_msgs.msg import ColorRGBA

    return ColorRGBA(r=float(rgb[0]), g=float(rgb[1]), b=float(rgb[2]), a=float(alpha))


def vehicle_markers(columns: Mapping[str, np.ndarray], stamp_ns: int):
    """The ``/evoscen/markers`` message for one world state (columns of the world table)."""
    from visualization_msgs.msg import Marker, MarkerArray

    stamp = stamp_from_ns(stamp_ns)
    out = MarkerArray()
    markers = []
    for i in range(len(columns["id"])):
        vid = int(columns["id"][i])
        yaw = float(columns["yaw"][i])
        box = Marker()
        box.header.stamp = stamp
        box.header.frame_id = MAP_FRAME
        box.ns = "vehicles"
        box.id = vid
        box.type = Marker.CUBE
        box.action = Marker.ADD
        box.pose.position.x = float(columns["x"][i])
        box.pose.position.y = float(columns["y"][i])
        box.pose.position.z = 0.5 * VEHICLE_HEIGHT_M
        box.pose.orientation.z = math.sin(0.5 * yaw)
        box.pose.orientation.w = math.cos(0.5 * yaw)
        box.scale.x = float(columns["length"][i])
        box.scale.y = float(columns["width"][i])
        box.scale.z = VEHICLE_HEIGHT_M
        box.color = _color(vehicle_color(columns["policy"][i], columns["length"][i]))
        label = Marker()
        label.header = box.header
        label.ns = "labels"
        label.id = vid
        label.type = Marker.TEXT_VIEW_FACING
        label.action = Marker.ADD
        label.pose.position.x = box.pose.position.x
        label.pose.position.y = box.pose.position.y
        label.pose.position.z = VEHICLE_HEIGHT_M + 1.0
        label.pose.orientation.w = 1.0
        label.scale.z = 1.2
        label.color = _color((1.0, 1.0, 1.0))
        label.text = f"{vid}  {float(columns['speed'][i]) * 3.6:.0f} km/h"
        markers += (box, label)
    out.markers = markers
    return out


def road_markers(road, stamp_ns: int = 0):
    """The ``/evoscen/map_markers`` message: lane lines and road edges of ``road``."""
    from geometry_msgs.msg import Point
    from visualization_msgs.msg import Marker, MarkerArray

    stamp = stamp_from_ns(stamp_ns)
    markers = []
    for k, line in enumerate(road.lane_markings()):
        m = Marker()
        m.header.stamp = stamp
        m.header.frame_id = MAP_FRAME
        m.ns = line.kind
        m.id = k
        m.type = Marker.LINE_LIST
        m.action = Marker.ADD
        m.pose.orientation.w = 1.0
        m.scale.x = float(line.width_m)
        m.color = _color((1.0, 1.0, 1.0) if line.color != "yellow" else (1.0, 0.85, 0.0))
        xs, ys = np.asarray(line.x_m), np.asarray(line.y_m)
        points = []
        for j in range(len(xs) - 1):
            if line.type == "broken" and j % 3:
                continue
            points += (Point(x=float(xs[j]), y=float(ys[j])), Point(x=float(xs[j + 1]), y=float(ys[j + 1])))
        m.points = points
        markers.append(m)
    out = MarkerArray()
    out.markers = markers
    return out
