"""The BV nodes of a scenario: which BVs each BV node hosts (``bvs.nodes``; docs/architecture.md §5, "BV nodes").

One rule for every runner and node: the launcher starts one BV node per :class:`BvNode`, the
simulation node waits for each, the recorder records each one's command topic, the in-process
runner drives and records the same partition (:class:`PartitionedDriver`), so the graph's bag
and the in-process bag of one partition are the same bytes.

* ``single``: one node ``evoscen_bv`` for all BVs (topic ``/evoscen/commands/bv``);
* ``by_policy``: one node per driver type present, in the order of the policy codes — for the
  learned drivers competitive, mutual, cooperative (a policy whose share of the mix is 0 has no
  node), otherwise one node named after ``bvs.driver`` (``evoscen_bv_level0``, ``..._nilsson``,
  ``..._mobil``, a plug-in's);
* N: the BVs in N runs of consecutive ids, as even as can be (``evoscen_bv_0`` … ``evoscen_bv_<N-1>``;
  a node gets no BV when N exceeds the BVs, and still answers every step with an empty table).

A vehicle's id and its driver type are fixed for the run: an entry at a window edge
(:mod:`evoscen_sim.physics.window`) is the same slot, id and policy code, starting a new trip, so it
stays with its node. No BVs, no BV node, whatever the mode.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
from evoscen_contract.contract import POLICY_CODES, bv_node_name, command_topic

from evoscen_sim.config.scenario_config import ScenarioConfig, mix_counts
from evoscen_sim.errors import InputError
from evoscen_sim.model_registry import checked_answer
from evoscen_sim.scenario_builders import build_bv_driver, bv_indices, bv_policy_codes, scenario_rngs


@dataclass(frozen=True)
class BvNode:
    """One BV node: its name, its command topic and the world indices of the BVs it hosts."""

    name: str
    topic: str
    rows: np.ndarray
    """World indices (= ids) of its BVs, ascending."""


def _part_name(driver: str) -> str:
    """A driver's name as a part of a ROS node name (letters, digits, underscores)."""
    return re.sub(r"[^A-Za-z0-9_]", "_", driver)


def bv_nodes(cfg: ScenarioConfig) -> tuple[BvNode, ...]:
    """The BV nodes of ``cfg`` (module docstring), in the contract's order."""
    rows = bv_indices(cfg)
    mode = cfg.bvs.nodes
    if rows.size == 0:
        return ()
    if mode == "single":
        parts = [("", rows)]
    elif mode == "by_policy":
        # the same draw as the world's spawn layout (the first of the spawn stream): vehicle
        # 1 + k has code codes[k] in both (checked by a test against the world's policy column)
        codes = bv_policy_codes(cfg, scenario_rngs(cfg.seed)["spawn"])
        if cfg.bvs.driver != "learned":
            parts = [(_part_name(cfg.bvs.driver), rows)]
        else:
            # in the mix's order (competitive, mutual, cooperative), the policies present
            parts = [(name, rows[codes == POLICY_CODES[name]]) for name, k in mix_counts(cfg).items() if k > 0]
    else:
        parts = [(str(k), chunk) for k, chunk in enumerate(np.array_split(rows, int(mode)))]
    out = []
    for part, r in parts:
        name = bv_node_name(part)
        out.append(BvNode(name=name, topic=command_topic(name), rows=np.asarray(r, dtype=np.int64)))
    return tuple(out)


def bv_node_names(cfg: ScenarioConfig) -> list[str]:
    """The names of :func:`bv_nodes`, in order."""
    return [n.name for n in bv_nodes(cfg)]


def bv_node_of(cfg: ScenarioConfig, name: str) -> BvNode:
    """The BV node named ``name`` in ``cfg``'s partition; a one-line InputError naming the valid ones."""
    nodes = bv_nodes(cfg)
    for node in nodes:
        if node.name == name:
            return node
    valid = ", ".join(n.name for n in nodes) or "none (bvs.count is 0)"
    raise InputError(f"BV node '{name}' is not one of this scenario's BV nodes (bvs.nodes = {cfg.bvs.nodes}): "
                     f"{valid}")


class PartitionedDriver:
    """The BVs driven as the BV nodes drive them: one driver per node, each over its own BVs.

    ``act(view)`` returns ``(throttle, lane_change)`` over all BVs in world-index order, as the
    one driver of ``single`` does; ``parts`` are the nodes and their drivers.
    """

    def __init__(self, parts: list[tuple[BvNode, object]], bvs: np.ndarray) -> None:
        self.parts = parts
        self.vehicles = np.asarray(bvs, dtype=np.int64)
        pos = {int(v): k for k, v in enumerate(self.vehicles)}
        self.positions = [np.array([pos[int(r)] for r in node.rows], dtype=np.int64) for node, _ in parts]

    def act(self, view) -> tuple[np.ndarray, np.ndarray]:
        throttle = np.zeros(self.vehicles.size)
        lane_change = np.zeros(self.vehicles.size, dtype=np.int64)
        for (_, driver), pos in zip(self.parts, self.positions):
            thr, lc = checked_answer(driver, driver.act(view))  # each node's answer checked as its controller does
            throttle[pos], lane_change[pos] = thr, lc
        return throttle, lane_change




def build_bv_drivers(cfg: ScenarioConfig):
    """The BVs' driver as the BV nodes of ``bvs.nodes`` drive them (the in-process runner's): for one
    node its driver, else a :class:`PartitionedDriver` of one driver per BV node
    (:func:`evoscen_sim.scenario_builders.build_bv_driver` for each node's share)."""
    nodes = bv_nodes(cfg)
    if len(nodes) <= 1:
        return build_bv_driver(cfg)
    return PartitionedDriver([(node, build_bv_driver(cfg, node.rows)) for node in nodes], bv_indices(cfg))
