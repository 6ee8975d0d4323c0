"""The compiled one-state SUT leader/TTC equals the numpy definitions bit for bit.

The simulation node's live exposure events use :func:`evoscen_sim.safety.sut_leader_ttc_state`;
the evaluator scores with :func:`sut_leader` / :func:`sut_ttc` over whole runs. The live
events and the scores must never disagree, so the two are compared here on hand-placed
edge cases, random dense states and every state of a simulated run.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from evoscen_sim.safety import sut_leader, sut_leader_ttc_state, sut_ttc


def _numpy(s, d, v, length, width, sut):  # noqa: ANN001, ANN202
    leader = int(sut_leader(s, d, length, width, sut)[0])
    return leader, float(sut_ttc(s, d, v, length, width, sut))


def _same(s, d, v, length, width, sut) -> tuple[int, float]:  # noqa: ANN001
    arrays = [np.ascontiguousarray(x, dtype=float) for x in (s, d, v, length, width)]
    want = _numpy(*arrays, sut)
    got = sut_leader_ttc_state(*arrays, sut)
    assert got[0] == want[0], f"leader {got[0]} != {want[0]}"
    # bit-identical, inf and signed zero included
    assert np.float64(got[1]).tobytes() == np.float64(want[1]).tobytes(), f"ttc {got[1]!r} != {want[1]!r}"
    return want


W, L = 1.8, 4.5


@pytest.mark.parametrize("case, svd, leader, ttc", [
    # the SUT is vehicle 0; svd = s, d, v of every vehicle
    ("no one ahead", ([0.0, -10.0], [0.0, 0.0], [20.0, 30.0]), -1, math.inf),
    ("ahead, closing", ([0.0, 24.5], [0.0, 0.0], [20.0, 10.0]), 1, 2.0),
    ("ahead, opening", ([0.0, 24.5], [0.0, 0.0], [20.0, 25.0]), 1, math.inf),
    ("ahead, same speed", ([0.0, 24.5], [0.0, 0.0], [20.0, 20.0]), 1, math.inf),
    ("bodies overlap: gap < 0 -> 0", ([0.0, 2.0], [0.0, 0.0], [20.0, 10.0]), 1, 0.0),
    ("beside, no lateral overlap", ([0.0, 24.5], [0.0, 1.8], [20.0, 10.0]), -1, math.inf),
    ("cutting in: lateral overlap", ([0.0, 24.5], [0.0, 1.79], [20.0, 10.0]), 1, 2.0),
    ("level with the SUT is not ahead", ([0.0, 0.0], [0.0, 0.0], [20.0, 10.0]), -1, math.inf),
    ("nearest of several", ([0.0, 60.0, 30.0, 45.0], [0.0, 0.0, 0.5, -0.5], [20.0, 0.0, 10.0, 0.0]), 2, 2.55),
    ("equal distances: the first", ([0.0, 30.0, 30.0], [0.0, 0.4, -0.4], [20.0, 10.0, 5.0]), 1, 2.55),
])
def test_edge_cases(case: str, svd: tuple, leader: int, ttc: float) -> None:
    s, d, v = (np.array(x) for x in svd)
    got = _same(s, d, v, np.full(s.size, L), np.full(s.size, W), 0)
    assert got[0] == leader, case
    assert got[1] == pytest.approx(ttc), case


def test_sut_not_first_and_nan() -> None:
    s = np.array([30.0, 0.0, 24.5, np.nan])
    d = np.array([0.0, 0.0, 0.2, 0.0])
    v = np.array([10.0, 20.0, 12.0, 10.0])
    assert _same(s, d, v, np.full(4, L), np.full(4, W), 1)[0] == 2


def test_random_dense_states() -> None:
    rng = np.random.default_rng(7)
    for _ in range(3000):
        n = int(rng.integers(2, 30))
        s = np.round(rng.uniform(0.0, 120.0, n), int(rng.integers(0, 3)))  # rounding makes ties and overlaps
        d = rng.choice([-3.75, 0.0, 3.75], n) + rng.normal(0.0, 0.8, n)
        v = rng.uniform(0.0, 35.0, n)
        length = rng.uniform(3.5, 12.0, n)
        width = rng.uniform(1.6, 2.6, n)
        _same(s, d, v, length, width, int(rng.integers(0, n)))


def test_every_state_of_a_run() -> None:
    from evoscen_bringup.scenario import build_scenario
    from evoscen_sim.config import load_scenario_config
    from evoscen_sim.scenario import SUT_INDEX

    sc = build_scenario(load_scenario_config(None, {"steps": 1500}))
    w = sc.world
    leaders = set()
    for _ in range(1500):
        leaders.add(_same(w.s, w.d, w.v, w.length, w.width, SUT_INDEX)[0])
        sc.step()
    assert len(leaders) > 1  # the SUT had leaders (and maybe none) during the run
