"""What the in-process runner's recorders need of a scenario: its recording part, no more.

:class:`~evoscen_record.step_recorder.StepRecorder` and
:class:`~evoscen_record.bag_writer.ProcessRecorder` take a :class:`RecordingPlan`, not the
scenario's whole configuration: the runner resolves the configuration once, at its door
(:mod:`evoscen_bringup.plan`), and hands each room its part.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping


@dataclass(frozen=True)
class BvTopic:
    """One BV node as the bag records it: its name, its command topic, and where its BVs lie among
    all BVs (in world-index order): the rows of the BV commands it answers for."""

    node: str
    topic: str
    positions: tuple[int, ...]


@dataclass(frozen=True)
class RecordingPlan:
    """The recording part of a run (docs/recording.md): what the bag's messages and file need."""

    dt_s: float
    """The step (s): the messages' time base."""
    bv_count: int
    """BVs in the world (world indices 1..bv_count)."""
    bv_topics: tuple[BvTopic, ...]
    """The BV nodes of ``bvs.nodes``, in the contract's order (none without BVs)."""
    compression: str
    """``recording.compression``: the MCAP chunks' compression."""
    chunk_size_bytes: int
    """``recording.chunk_size_bytes``."""
    markers_every: int
    """``recording.markers_every``: vehicle markers every this many steps (0: never)."""
    scenario_record: Mapping[str, str]
    """The scenario's metadata record, written first in the bag
    (:func:`evoscen_record.scenario_record.scenario_metadata`: the scenario as YAML text, the map's hash)."""

    @property
    def bv_nodes(self) -> list[str]:
        """The BV nodes' names, in order (the contract's command topics)."""
        return [b.node for b in self.bv_topics]
