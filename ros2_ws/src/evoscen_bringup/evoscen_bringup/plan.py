"""The in-process runner's plan: a scenario's configuration resolved once, at the runner's door.

:func:`plan_of` resolves a :class:`~evoscen_sim.config.scenario_config.ScenarioConfig` into a
:class:`RunPlan`, and :func:`evoscen_bringup.inprocess.run_plan` runs it; below this door no room
receives the whole configuration, each gets its part:

* the world (:attr:`RunPlan.scenario`): the world and the drivers that command it, built here (a
  driver's factory is handed the scenario's configuration: docs/plugins.md);
* the drivers (:class:`DriverPlan`): the BV nodes the drivers answer for;
* the recording (:class:`~evoscen_record.recording_plan.RecordingPlan`): what the recorders need,
  with the scenario's metadata record, written once here;
* the evaluation (:class:`EvaluationPlan`): the evaluation settings the step loop's exposures and
  the scorer use, the step, and the scenario as the bag records it (the report's ``run`` section).

The scorer takes the configuration's evaluation settings as they are, with no YAML round trip: they
equal those an evaluation of the bag reads back from its scenario record (tests/test_plan.py), so
the run's report is the bag's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from evoscen_contract.contract import NODE_BV
from evoscen_record.recording_plan import BvTopic, RecordingPlan
from evoscen_record.scenario_record import metadata_record, portable_map_ref, recorded_scenario
from evoscen_sim.config.scenario_config import EvaluationConfig, ScenarioConfig
from evoscen_sim.nodes.bv_nodes import bv_nodes
from evoscen_sim.scenario_builders import bv_indices

from evoscen_bringup.scenario import Scenario, build_scenario


@dataclass(frozen=True)
class DriverPlan:
    """The drivers' part: the BV nodes of ``bvs.nodes`` whose share of the BVs the drivers answer for."""

    bv_nodes: tuple[str, ...]
    """Their names, in the contract's order (none without BVs)."""

    @property
    def fault_node(self) -> str:
        """The node a BV driver's fault names: the one BV node, else the BVs' controller (``NODE_BV``)."""
        return self.bv_nodes[0] if len(self.bv_nodes) == 1 else NODE_BV


@dataclass(frozen=True)
class EvaluationPlan:
    """The evaluation's part: what the step loop's exposures, the scorer and the report need."""

    settings: EvaluationConfig
    """The scenario's ``evaluation`` section: the exposures' and the scores' settings."""
    dt_s: float
    """The step (s)."""
    scenario: dict
    """The scenario as the bag records it (:func:`~evoscen_record.scenario_record.recorded_scenario`):
    the report's ``run`` section, and :attr:`RunData.scenario <evoscen_eval.scoring.rundata.RunData.scenario>`."""


@dataclass(frozen=True)
class RunPlan:
    """A run resolved from its configuration (module docstring): each room's part."""

    scenario: Scenario
    """The world part: the world and the drivers that command it."""
    steps: int
    """Steps to run."""
    drivers: DriverPlan
    evaluation: EvaluationPlan
    recording: RecordingPlan | None
    """None: the run records no bag."""


def driver_plan_of(cfg: ScenarioConfig) -> DriverPlan:
    """The drivers' part of ``cfg``."""
    return DriverPlan(bv_nodes=tuple(n.name for n in bv_nodes(cfg)))


def evaluation_plan_of(cfg: ScenarioConfig, scenario: dict | None = None) -> EvaluationPlan:
    """The evaluation's part of ``cfg`` (``scenario``: its :func:`recorded_scenario`, if at hand)."""
    recorded = recorded_scenario(cfg) if scenario is None else scenario
    return EvaluationPlan(settings=cfg.evaluation, dt_s=float(cfg.dt_s), scenario=recorded)


def recording_plan_of(cfg: ScenarioConfig, scenario: dict | None = None) -> RecordingPlan:
    """The recording part of ``cfg`` (``scenario``: its :func:`recorded_scenario`, if at hand): the BV
    nodes with their topics and BVs, the ``recording`` section, the scenario's metadata record."""
    rows = bv_indices(cfg)
    topics = tuple(BvTopic(node=n.name, topic=n.topic, positions=tuple(int(p) for p in np.searchsorted(rows, n.rows)))
                   for n in bv_nodes(cfg))
    recorded = recorded_scenario(cfg) if scenario is None else scenario
    rec = cfg.recording
    return RecordingPlan(dt_s=cfg.dt_s, bv_count=int(rows.size), bv_topics=topics, compression=rec.compression,
                         chunk_size_bytes=rec.chunk_size_bytes, markers_every=rec.markers_every,
                         scenario_record=metadata_record(recorded, portable_map_ref(cfg.map)[1]))


def plan_of(cfg: ScenarioConfig, *, recorded: bool = True, steps: int | None = None,
            scenario: Scenario | None = None) -> RunPlan:
    """The plan of a run of ``cfg``: ``steps`` steps (default ``cfg.steps``), a bag recorded unless
    ``recorded`` is false, on ``scenario`` (default: built from ``cfg``, its BVs driven as their BV nodes
    drive them when the run is recorded, else by one driver of all BVs: the same world and scores at a
    third of the per-call cost, docs/performance.md "Experiments")."""
    sc = scenario if scenario is not None else build_scenario(cfg, partitioned=recorded)
    record = recorded_scenario(cfg)
    return RunPlan(scenario=sc, steps=cfg.steps if steps is None else steps, drivers=driver_plan_of(cfg),
                   evaluation=evaluation_plan_of(cfg, record),
                   recording=recording_plan_of(cfg, record) if recorded else None)
