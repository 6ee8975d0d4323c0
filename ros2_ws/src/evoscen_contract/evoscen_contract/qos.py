"""QoS profile descriptions shared by live nodes and the recorder.

A :class:`QosSpec` is a small, hashable, ROS-free description of a topic's QoS
(reliability, durability, history, depth). It converts both ways that evoscen
needs:

* :meth:`QosSpec.to_rclpy` -> ``rclpy.qos.QoSProfile`` for publishers and
  subscriptions (rclpy is imported lazily, so the description itself needs no ROS);
* :meth:`QosSpec.to_rosbag2` -> the mapping rosbag2 (Jazzy, metadata version 9)
  writes for one *offered* profile, used both in ``metadata.yaml``
  (``topic_metadata.offered_qos_profiles``, a YAML list) and in the MCAP channel
  metadata (``offered_qos_profiles``, the same list dumped as a YAML string).

Deadline, lifespan and liveliness lease are left at their defaults (no deadline,
infinite lifespan, automatic liveliness). A live Fast DDS endpoint reports these as
``RMW_DURATION_INFINITE`` (``sec: 9223372036, nsec: 854775807``), which is what
``ros2 bag record`` stores; we store the same so ``ros2 bag play`` re-offers the
profile unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any

RELIABILITIES: tuple[str, ...] = ("reliable", "best_effort")
DURABILITIES: tuple[str, ...] = ("volatile", "transient_local")
HISTORIES: tuple[str, ...] = ("keep_last", "keep_all")

#: ``RMW_DURATION_INFINITE`` as rosbag2 writes it (``{sec, nsec}``).
INFINITE_DURATION: dict[str, int] = {"sec": 9223372036, "nsec": 854775807}


@dataclass(frozen=True)
class QosSpec:
    """ROS-free description of one QoS profile.

    Attributes:
        reliability: ``"reliable"`` or ``"best_effort"``.
        durability: ``"volatile"`` or ``"transient_local"``.
        history: ``"keep_last"`` or ``"keep_all"``.
        depth: queue depth in messages (``keep_last``: >= 1; ``keep_all``: 0, as rosbag2 writes it).
    """

    reliability: str = "reliable"
    durability: str = "volatile"
    history: str = "keep_last"
    depth: int = 10

    def __post_init__(self) -> None:
        """Validate the enumerations and the depth (ValueError on a bad value)."""
        if self.reliability not in RELIABILITIES:
            raise ValueError(f"QosSpec.reliability: {self.reliability!r} not in {RELIABILITIES}")
        if self.durability not in DURABILITIES:
            raise ValueError(f"QosSpec.durability: {self.durability!r} not in {DURABILITIES}")
        if self.history not in HISTORIES:
            raise ValueError(f"QosSpec.history: {self.history!r} not in {HISTORIES}")
        minimum = 1 if self.history == "keep_last" else 0
        if not isinstance(self.depth, int) or isinstance(self.depth, bool) or self.depth < minimum:
            raise ValueError(f"QosSpec.depth: {self.depth!r} is not an integer >= {minimum} (history {self.history})")

    def to_rclpy(self) -> Any:
        """Return the equivalent ``rclpy.qos.QoSProfile`` (imports rclpy lazily)."""
        from rclpy.qos import (
            DurabilityPolicy,
            HistoryPolicy,
            QoSProfile,
            ReliabilityPolicy,
        )

        return QoSProfile(
            history=(
                HistoryPolicy.KEEP_LAST if self.history == "keep_last" else HistoryPolicy.KEEP_ALL
            ),
            depth=self.depth,
            reliability=(
                ReliabilityPolicy.RELIABLE
                if self.reliability == "reliable"
                else ReliabilityPolicy.BEST_EFFORT
            ),
            durability=(
                DurabilityPolicy.TRANSIENT_LOCAL
                if self.durability == "transient_local"
                else DurabilityPolicy.VOLATILE
            ),
        )

    def to_rosbag2(self) -> dict[str, Any]:
        """Return one offered QoS profile as rosbag2 Jazzy (metadata version 9) writes it.

        Key order follows rosbag2 (history, depth, reliability, durability, deadline,
        lifespan, liveliness, liveliness_lease_duration, avoid_ros_namespace_conventions).
        """
        return {
            "history": self.history,
            "depth": self.depth,
            "reliability": self.reliability,
            "durability": self.durability,
            "deadline": dict(INFINITE_DURATION),
            "lifespan": dict(INFINITE_DURATION),
            "liveliness": "automatic",
            "liveliness_lease_duration": dict(INFINITE_DURATION),
            "avoid_ros_namespace_conventions": False,
        }

    def short(self) -> str:
        """Return a compact human-readable form, e.g. ``reliable, volatile, keep_last(100)``."""
        hist = f"keep_last({self.depth})" if self.history == "keep_last" else "keep_all"
        return f"{self.reliability}, {self.durability}, {hist}"


def rosbag2_qos_yaml(profiles: list[QosSpec] | tuple[QosSpec, ...]) -> str:
    """Return the offered profiles as the YAML string rosbag2 stores in MCAP channel metadata.

    rosbag2 (``serialize_rclcpp_qos_vector``) dumps the profile list with yaml-cpp in
    block style; PyYAML with ``sort_keys=False`` and ``default_flow_style=False``
    gives the same layout. Deterministic: depends only on ``profiles``.
    """
    return _qos_yaml(tuple(profiles))


@lru_cache(maxsize=64)
def _qos_yaml(profiles: tuple[QosSpec, ...]) -> str:
    """:func:`rosbag2_qos_yaml`'s text, dumped once per profile list and process (a recorder opened
    per run dumped it for every topic: ~3 ms a run)."""
    import yaml

    return yaml.safe_dump(
        [p.to_rosbag2() for p in profiles], sort_keys=False, default_flow_style=False
    )
