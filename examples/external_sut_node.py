#!/usr/bin/env python3
"""Your own system under test (SUT) as an external ROS 2 node — written only against
evoscen's topic contract (docs/topics.md): rclpy, standard messages and numpy,
no evoscen package.

    # terminal 1: the evoscen graph, without evoscen's own SUT node, on a known domain
    python scripts/run_scenario.py --mode graph --external-sut --domain-id 42 --steps 1000 --out runs/ext
    # terminal 2 (within the start-up timeout, 60 s): this node on the same domain
    ROS_DOMAIN_ID=42 ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST \\
        python examples/external_sut_node.py --ros-args -p steps:=1000

What it does, per world message (``/evoscen/world`` at t_k, one answer each: lockstep):

1. decode the world table (a ``sensor_msgs/PointCloud2`` used as a table) by field name;
2. find the SUT's row (``role == 1``);
3. compute the policy below (:func:`policy`, pure numpy — a test recomputes it from the bag);
4. publish one command row on ``/evoscen/commands/sut`` (float64 columns ``id``,
   ``throttle``, ``lane_change``) with ``header.stamp`` = the world message's stamp and
   ``frame_id`` ``"map"``, QoS reliable / volatile / keep_all.

It exits (status 0) on the ``evoscen/run_end`` event of ``/evoscen/events``; 130 on Ctrl-C;
1 when no world message came for ``idle_timeout_s``.

**The policy** (a deliberately simple example; constants in :class:`PolicyParams`):

* longitudinal — constant-time-gap car following: the leader is the nearest vehicle ahead
  occupying the SUT's current or target lane (``lane`` or ``target_lane`` equal to it) within
  ``look_ahead_m``; with bumper-to-bumper gap g, own speed v and leader speed v_l::

      a_follow = k_gap * (g - (min_gap_m + time_gap_s * v)) + k_speed * (v_l - v)
      a_free   = k_free * (desired_speed_mps - v)
      a        = min(a_free, a_follow)          (a_free without a leader)
      a        = -max_brake_mps2                 if g < min_gap_m

  and the throttle is ``a / max_accel_mps2`` for a >= 0, ``a / max_brake_mps2`` otherwise,
  clipped to [-1, 1] (docs/method.md §2, vehicle limits: +1 = +3.0 m/s², -1 = -8.0 m/s²). On the
  merge lane (lane 0) the end of the lane's full width (s = 900 m) is a standing leader.
* lateral — request a change to the LEFT (+1) when no lane change is in progress, a left
  lane exists (lane < 4), and either the SUT is on the merge lane or its leader is closer
  than ``overtake_gap_m`` and slower than ``slow_leader_mps``; and the left lane is free:
  nobody occupying it within ``left_free_front_m`` ahead or ``left_free_rear_m`` behind
  (bumper to bumper). Never to the right.

Node parameters (``--ros-args -p name:=value``):

* ``steps`` [0]: the scenario's number of steps N. After the last step the simulation
  publishes the final state (stamp t_N = N * dt_s) that no controller answers; with
  ``steps`` > 0 the node leaves it unanswered. With 0 it answers it too: the simulation
  ignores that answer, but the recorder keeps it (one SUT command more in the bag).
* ``dt_s`` [0.1]: the scenario's step (s), for t_N.
* ``command_subscribers`` [2]: the node answers the first world message only once its
  command publisher is matched with this many subscribers — the simulation node and the
  recorder — so that no command is lost (the topic is volatile).
* ``idle_timeout_s`` [60]: give up (status 1) after this long without a world message.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import PointCloud2, PointField

WORLD_TOPIC = "/evoscen/world"
COMMAND_TOPIC = "/evoscen/commands/sut"
EVENTS_TOPIC = "/evoscen/events"
RUN_END = "evoscen/run_end"
COMMAND_FIELDS = ("id", "throttle", "lane_change")
ROLE_SUT = 1
MERGE_LANE, LEFTMOST_LANE = 0, 4
MERGE_LANE_FULL_WIDTH_END_M = 900.0

#: The contract's QoS of every per-step topic.
STEP_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE,
                      history=HistoryPolicy.KEEP_ALL)


@dataclass(frozen=True)
class PolicyParams:
    """Constants of the example policy (see the module docstring)."""

    desired_speed_mps: float = 30.0
    time_gap_s: float = 1.5
    min_gap_m: float = 2.0
    k_gap: float = 0.2          # 1/s²: acceleration per m of gap error
    k_speed: float = 0.6        # 1/s: acceleration per m/s of speed difference to the leader
    k_free: float = 0.5         # 1/s: acceleration per m/s below the desired speed
    look_ahead_m: float = 150.0
    max_accel_mps2: float = 3.0  # throttle +1 (docs/method.md §2: vehicle limits)
    max_brake_mps2: float = 8.0  # throttle -1
    slow_leader_mps: float = 28.0  # "X": overtake a leader slower than this ...
    overtake_gap_m: float = 60.0   # ... that is closer than this
    left_free_front_m: float = 30.0
    left_free_rear_m: float = 20.0


# ---------------------------------------------------------------------------- the table format

_NUMPY_TYPES = {PointField.INT8: "i1", PointField.UINT8: "u1", PointField.INT16: "i2", PointField.UINT16: "u2",
                PointField.INT32: "i4", PointField.UINT32: "u4", PointField.FLOAT32: "f4", PointField.FLOAT64: "f8"}


def table_columns(msg: PointCloud2) -> dict[str, np.ndarray]:
    """The columns of a PointCloud2 table by field name (float64 arrays, one entry per row)."""
    order = ">" if msg.is_bigendian else "<"
    dtype = np.dtype({"names": [f.name for f in msg.fields],
                      "formats": [order + _NUMPY_TYPES[f.datatype] for f in msg.fields],
                      "offsets": [f.offset for f in msg.fields],
                      "itemsize": msg.point_step})
    data = np.frombuffer(bytes(msg.data), dtype=np.uint8).reshape(msg.height, msg.row_step)
    rows = data[:, :msg.width * msg.point_step].copy().view(dtype).reshape(-1)
    return {name: rows[name].astype(np.float64) for name in dtype.names}


def command_message(stamp, vehicle_id: float, throttle: float, lane_change: float) -> PointCloud2:
    """One-row command table answering the world message stamped ``stamp``."""
    msg = PointCloud2()
    msg.header.stamp = stamp
    msg.header.frame_id = "map"
    msg.height, msg.width = 1, 1
    msg.fields = [PointField(name=name, offset=8 * k, datatype=PointField.FLOAT64, count=1)
                  for k, name in enumerate(COMMAND_FIELDS)]
    msg.is_bigendian = False
    msg.point_step = 8 * len(COMMAND_FIELDS)
    msg.row_step = msg.point_step
    msg.data = np.array([vehicle_id, throttle, lane_change], dtype="<f8").tobytes()
    msg.is_dense = True
    return msg


# ---------------------------------------------------------------------------- the policy

def policy(world: dict[str, np.ndarray], p: PolicyParams = PolicyParams()) -> tuple[float, float, float]:
    """``(sut id, throttle, lane_change)`` for the world table's columns (module docstring)."""
    sut = int(np.flatnonzero(world["role"] == ROLE_SUT)[0])
    s, v, length = world["s"], world["speed"], world["length"]
    lane, target = world["lane"].astype(int), world["target_lane"].astype(int)
    my_lane, my_target, me_s, me_v = lane[sut], target[sut], s[sut], v[sut]
    others = np.arange(len(s)) != sut
    half = 0.5 * (length + length[sut])             # centre distance at zero gap
    gap = (s - me_s) - half                        # bumper-to-bumper gap, ahead (> 0) ...
    gap_behind = (me_s - s) - half                 # ... and behind

    def occupying(lane_index: int) -> np.ndarray:
        return others & ((lane == lane_index) | (target == lane_index))

    ahead = (occupying(my_lane) | occupying(my_target)) & (s > me_s) & (gap < p.look_ahead_m)
    leader_gap, leader_v = np.inf, np.inf
    if ahead.any():
        k = np.flatnonzero(ahead)[np.argmin(gap[ahead])]
        leader_gap, leader_v = gap[k], v[k]
    if my_lane == MERGE_LANE:                      # the lane end as a standing leader
        end_gap = MERGE_LANE_FULL_WIDTH_END_M - me_s - 0.5 * length[sut]
        if end_gap < leader_gap:
            leader_gap, leader_v = end_gap, 0.0

    accel = p.k_free * (p.desired_speed_mps - me_v)
    if np.isfinite(leader_gap):
        follow = p.k_gap * (leader_gap - (p.min_gap_m + p.time_gap_s * me_v)) + p.k_speed * (leader_v - me_v)
        accel = min(accel, follow)
        if leader_gap < p.min_gap_m:
            accel = -p.max_brake_mps2
    throttle = accel / p.max_accel_mps2 if accel >= 0 else accel / p.max_brake_mps2
    throttle = float(np.clip(throttle, -1.0, 1.0))

    lane_change = 0.0
    settled = world["lane_change"][sut] == 0 and my_lane == my_target
    wants_left = my_lane == MERGE_LANE or (leader_gap < p.overtake_gap_m and leader_v < p.slow_leader_mps)
    if settled and my_lane < LEFTMOST_LANE and wants_left:
        left = occupying(my_lane + 1)
        blocked = left & (((s >= me_s) & (gap < p.left_free_front_m)) | ((s < me_s) & (gap_behind < p.left_free_rear_m)))
        if not blocked.any():
            lane_change = 1.0
    return float(world["id"][sut]), throttle, lane_change


# ---------------------------------------------------------------------------- the node

class ExternalSut(Node):
    """Answers every world message of the run with the policy's command (lockstep)."""

    def __init__(self) -> None:
        super().__init__("my_external_sut")
        self.steps = int(self.declare_parameter("steps", 0).value)
        self.dt_s = float(self.declare_parameter("dt_s", 0.1).value)
        self.command_subscribers = int(self.declare_parameter("command_subscribers", 2).value)
        self.idle_timeout_s = float(self.declare_parameter("idle_timeout_s", 60.0).value)
        self.final_stamp_ns = round(self.steps * self.dt_s * 1e9) if self.steps > 0 else None
        self.params = PolicyParams()
        self.pub = self.create_publisher(PointCloud2, COMMAND_TOPIC, STEP_QOS)
        self.create_subscription(PointCloud2, WORLD_TOPIC, self.on_world, STEP_QOS)
        self.create_subscription(DiagnosticArray, EVENTS_TOPIC, self.on_events, STEP_QOS)
        self.pending: list[PointCloud2] = []   # world messages that came before the publisher was matched
        self.create_timer(0.01, self.answer_pending)
        self.done = False
        self.answered = 0
        self.last_world = time.monotonic()

    def on_world(self, msg: PointCloud2) -> None:
        self.last_world = time.monotonic()
        self.pending.append(msg)
        self.answer_pending()

    def answer_pending(self) -> None:
        """Answer the queued world messages, in order, once the command publisher is matched."""
        if not self.pending or self.pub.get_subscription_count() < self.command_subscribers:
            return
        for msg in self.pending:
            stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            if self.final_stamp_ns is not None and stamp_ns >= self.final_stamp_ns:
                continue  # the final state: nothing to answer
            vehicle_id, throttle, lane_change = policy(table_columns(msg), self.params)
            self.pub.publish(command_message(msg.header.stamp, vehicle_id, throttle, lane_change))
            self.answered += 1
        self.pending.clear()

    def on_events(self, msg: DiagnosticArray) -> None:
        if any(status.name == RUN_END for status in msg.status):
            self.done = True


def main(args: list[str] | None = None) -> int:
    rclpy.init(args=args)
    node = ExternalSut()
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    status = 0
    try:
        while not node.done:
            executor.spin_once(timeout_sec=0.1)
            if time.monotonic() - node.last_world > node.idle_timeout_s:
                print(f"error: no world message on {WORLD_TOPIC} for {node.idle_timeout_s:g} s", file=sys.stderr)
                status = 1
                break
        node.pub.wait_for_all_acked(Duration(seconds=2))  # the last command reaches the recorder
        print(f"{node.get_name()}: answered {node.answered} world messages", file=sys.stderr)
    except (KeyboardInterrupt, ExternalShutdownException):
        status = 130
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return status


if __name__ == "__main__":
    sys.exit(main())
