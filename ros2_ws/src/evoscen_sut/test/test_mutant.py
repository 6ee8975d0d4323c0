"""SUT mutants (evoscen_sut.mutant, evoscen_sut.mutants; docs/mutants.md): each operator degrades
its base model in the intended way and nothing else, in hand-built situations.

MOBIL situations are test_mobil.py's (defaults, vehicles 4.8 m): ego in lane 1 at s = 300,
25 m/s, a slow leader 25.2 m ahead (bumper) at 20 m/s, lane 2 free — MOBIL changes left;
with a vehicle 10.2 m behind in lane 2 at 35 m/s it would have to brake at 9 m/s² > b_safe = 4,
so intact MOBIL keeps its lane.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from evoscen_bringup.inprocess import run_inprocess
from evoscen_sim.config.scenario_config import load_scenario_config
from evoscen_sim.errors import InputError
from evoscen_sim.model_registry import ModelSpec, create_driver, register_model, unregister_model
from evoscen_sim.loop.hand_built import hand_built_world
from evoscen_sim.loop.view import WorldView
from evoscen_sim.road.road_model import load_road
from evoscen_sim.scenario_builders import build_sut_driver
from evoscen_sut import mutant as M
from evoscen_sut.mutants import LIBRARY, Mutant, mutant_overrides

EGO = [0]


@pytest.fixture(scope="module")
def road():
    return load_road()


@pytest.fixture(scope="module")
def base_cfg():
    return load_scenario_config(None)


def cfg_for(base: str, operator: str, **params) -> object:
    over = {"sut.model": "mutant", "models.mutant.base": base, "models.mutant.operator": operator}
    over.update({f"models.mutant.{k}": str(v) for k, v in params.items()})
    return load_scenario_config(None, over)


def pair(base: str, operator: str, seed: int = 0, **params):
    """(intact driver, mutant driver) of the ego (row 0), each with its own generator seeded ``seed``."""
    cfg = cfg_for(base, operator, **params)
    intact = create_driver(base, "sut", EGO, cfg, np.random.default_rng(seed))
    mutant = create_driver("mutant", "sut", EGO, cfg, np.random.default_rng(seed))
    return intact, mutant


def blocked_left(road):
    return hand_built_world(road, s=[300.0, 330.0, 285.0], lane=[1, 1, 2], speed=[25.0, 20.0, 35.0])


# ------------------------------------------------------------------ a scripted plug-in base
class Scripted:
    """A user's plug-in SUT that replays a command script (one entry per call of ``act``)."""

    def __init__(self, vehicles, script) -> None:
        self.vehicles, self.script, self.k = vehicles, script, 0

    def act(self, view):
        thr, lc = self.script[min(self.k, len(self.script) - 1)]
        self.k += 1
        return np.array([thr]), np.array([lc])


SCRIPT = [(0.5, 0), (-0.5, 1), (0.1, 0), (-0.1, -1), (-0.8, 0), (0.3, 0), (0.0, 1), (-0.3, 0)]


@pytest.fixture
def scripted():
    register_model(ModelSpec("scripted_sut", ("sut",), lambda v, p, c, r: Scripted(v, SCRIPT)))
    yield "scripted_sut"
    unregister_model("scripted_sut")


def run_script(road, operator: str, **params) -> tuple[np.ndarray, np.ndarray]:
    cfg = cfg_for("scripted_sut", operator, **params)
    drv = create_driver("mutant", "sut", EGO, cfg, np.random.default_rng(0))
    w = hand_built_world(road, s=[300.0], lane=[1], speed=[25.0])
    out = [drv.act(w) for _ in SCRIPT]
    return np.array([o[0][0] for o in out]), np.array([o[1][0] for o in out])


def test_user_plugin_as_base_and_control_operators(road, scripted) -> None:
    thr = np.array([c[0] for c in SCRIPT])
    lc = np.array([c[1] for c in SCRIPT])
    # reaction_time: both commands shifted by exactly N steps (first throttle, no change, before)
    t, c = run_script(road, "reaction_time", delay_steps=3)
    assert np.array_equal(t, np.r_[[thr[0]] * 3, thr[:-3]])
    assert np.array_equal(c, np.r_[[0, 0, 0], lc[:-3]])
    # late_lane_change: only the lane change shifted
    t, c = run_script(road, "late_lane_change", delay_steps=2)
    assert np.array_equal(t, thr) and np.array_equal(c, np.r_[[0, 0], lc[:-2]])
    # weak_braking: -0.5 -> -0.2 at factor 0.4, positive and zero unchanged, lane change unchanged
    t, c = run_script(road, "weak_braking", brake_factor=0.4)
    assert np.allclose(t, np.where(thr < 0, 0.4 * thr, thr)) and t[1] == pytest.approx(-0.2)
    assert np.array_equal(c, lc)
    # late_braking: braking weaker than the onset dropped, stronger kept
    t, c = run_script(road, "late_braking", brake_onset=0.25)
    assert np.array_equal(t, np.where((thr < 0) & (thr > -0.25), 0.0, thr)) and np.array_equal(c, lc)
    assert t[3] == 0.0 and t[4] == -0.8


def test_over_eager_needs_parameters_for_a_plugin(scripted) -> None:
    with pytest.raises(InputError, match=r"models\.mutant\.retune"):
        create_driver("mutant", "sut", EGO, cfg_for("scripted_sut", "over_eager"), np.random.default_rng(0))


# ------------------------------------------------------------------ perception
def test_blind_behind_accepts_the_gap_intact_mobil_refuses(road) -> None:
    w = blocked_left(road)
    intact, mutant = pair("mobil", "blind_behind")
    (ti, ci), (tm, cm) = intact.act(w), mutant.act(w)
    assert ci[0] == 0 and cm[0] == 1
    assert np.array_equal(ti, tm)  # the follower is behind: car following is unaffected
    # the base driver sees the ego and the leader only
    seen = mutant.perceived(w)
    assert seen.n == 2 and list(seen.ids) == [0, 1]


def test_blind_behind_changes_nothing_without_vehicles_behind(road) -> None:
    w = hand_built_world(road, s=[300.0, 330.0, 340.0], lane=[1, 1, 2], speed=[25.0, 20.0, 30.0])
    intact, mutant = pair("mobil", "blind_behind")
    for (ti, ci), (tm, cm) in ((intact.act(w), mutant.act(w)) for _ in range(5)):
        assert np.array_equal(ti, tm) and np.array_equal(ci, cm)


def test_short_view_leader_beyond_range_gives_free_road_throttle(road) -> None:
    # a standing vehicle 50 m ahead in the own lane: intact brakes, a 30 m view sees a free road
    w = hand_built_world(road, s=[300.0, 354.8], lane=[1, 1], speed=[25.0, 0.0])
    free = hand_built_world(road, s=[300.0], lane=[1], speed=[25.0])
    intact, mutant = pair("mobil", "short_view", view_m=30.0)
    _, ref = pair("mobil", "short_view", view_m=30.0)
    ti, _ = intact.act(w)
    tm, _ = mutant.act(w)
    tf, _ = create_driver("mobil", "sut", EGO, cfg_for("mobil", "short_view"), np.random.default_rng(0)).act(free)
    assert ti[0] < 0 and np.array_equal(tm, tf)
    # at 20 m it is seen
    w = hand_built_world(road, s=[300.0, 324.8], lane=[1, 1], speed=[25.0, 0.0])
    assert ref.act(w)[0][0] < 0


def test_stale_others_seen_delay_steps_ago_own_state_current(road, base_cfg) -> None:
    w = hand_built_world(road, s=[300.0, 330.0, 280.0], lane=[1, 1, 2], speed=[25.0, 20.0, 30.0])
    drv = create_driver("mutant", "sut", EGO, cfg_for("mobil", "stale", delay_steps=3), np.random.default_rng(0))
    history = []
    for k in range(6):
        seen = drv.perceived(w)
        history.append(w.s.copy())
        assert seen.s[0] == w.s[0] and seen.v[0] == w.v[0]  # own state current
        old = history[max(0, k - 3)]
        assert np.array_equal(seen.s[1:], old[1:])  # others 3 steps old (the oldest at the start)
        w.step(np.zeros(3), np.zeros(3, dtype=np.int64))


# ------------------------------------------------------------------ decision
def test_ignores_new_follower_changes_into_the_gap_with_intact_throttle(road) -> None:
    w = blocked_left(road)
    intact, mutant = pair("mobil", "ignores_new_follower")
    (ti, ci), (tm, cm) = intact.act(w), mutant.act(w)
    assert ci[0] == 0 and cm[0] == 1 and np.array_equal(ti, tm)
    # a vehicle behind in the own lane stays visible to the decision (only adjacent lanes are dropped)
    nf = mutant._without_new_followers(
        hand_built_world(road, s=[300.0, 330.0, 285.0, 280.0], lane=[1, 1, 2, 1], speed=[25.0, 20.0, 35.0, 25.0]))
    assert list(nf.ids) == [0, 1, 3]


def test_over_eager_presets_and_retune(road) -> None:
    cfg = cfg_for("mobil", "over_eager")
    drv = create_driver("mutant", "sut", EGO, cfg, np.random.default_rng(0))
    p = drv.base.params
    assert (p.threshold_mps2, p.bias_mps2, p.safe_decel_mps2) == (0.0, 0.0, 9.0)
    assert p.politeness == cfg.models.get("mobil", type(p)()).politeness  # the rest untouched
    # the fast follower's ã_n is clipped at -9 = -b_safe: eager MOBIL takes the gap
    w = blocked_left(road)
    intact = create_driver("mobil", "sut", EGO, cfg, np.random.default_rng(0))
    assert intact.act(w)[1][0] == 0 and drv.act(w)[1][0] == 1
    for base in ("nilsson", "stackelberg"):
        d = create_driver("mutant", "sut", EGO, cfg_for(base, "over_eager"), np.random.default_rng(0))
        for k, v in M.EAGER_PRESETS[base].items():
            assert getattr(d.base.params, k) == v
    d = create_driver("mutant", "sut", EGO, cfg_for("mobil", "over_eager", retune="politeness=0, safe_decel_mps2=6"),
                      np.random.default_rng(0))
    assert (d.base.params.politeness, d.base.params.safe_decel_mps2, d.base.params.threshold_mps2) == (0.0, 6.0, 0.0)
    for bad, msg in (("nonsense=1", "not a parameter of models.mobil"), ("politeness=99", r"models\.mobil\.politeness"),
                     ("politeness", "expected 'preset'")):
        with pytest.raises(InputError, match=msg):
            create_driver("mutant", "sut", EGO, cfg_for("mobil", "over_eager", retune=bad), np.random.default_rng(0))


# ------------------------------------------------------------------ control
def test_tailgating_sees_the_leader_farther(road) -> None:
    # leader 20 m ahead (bumper): the mutant's throttle is intact's with the leader 35 m ahead
    w = hand_built_world(road, s=[300.0, 324.8, 324.8], lane=[1, 1, 2], speed=[25.0, 22.0, 25.0])
    far = hand_built_world(road, s=[300.0, 339.8, 324.8], lane=[1, 1, 2], speed=[25.0, 22.0, 25.0])
    intact, mutant = pair("mobil", "tailgating", extra_gap_m=15.0)
    _, ref = pair("mobil", "tailgating", extra_gap_m=15.0)
    intact_far = create_driver("mobil", "sut", EGO, cfg_for("mobil", "tailgating"), np.random.default_rng(0))
    (ti, ci), (tm, cm), (tf, _) = intact.act(w), mutant.act(w), intact_far.act(far)
    assert np.array_equal(tm, tf) and tm[0] > ti[0]
    assert np.array_equal(cm, ci)  # the decision sees the true gap


# ------------------------------------------------------------------ identity and runners
@pytest.mark.parametrize("base", ["mobil", "stackelberg"])
def test_mutant_that_filters_nothing_equals_intact_over_a_run(base) -> None:
    # short_view beyond the road and tailgating by 0 m perceive everything exactly: the same
    # commands as the intact model at every step of a real run (same seed, same random draws)
    from evoscen_bringup.scenario import build_scenario

    sc = build_scenario(load_scenario_config(None, {"sut.model": base}))
    mutants = [build_sut_driver(cfg_for(base, "short_view", view_m=10000)),
               build_sut_driver(cfg_for(base, "tailgating", extra_gap_m=0))]
    requests = 0
    for _ in range(200):
        cmds = sc.commands()
        for m in mutants:
            t, c = m.act(sc.world)
            assert np.array_equal(t, cmds[2]) and np.array_equal(c, cmds[3])
        requests += int(cmds[3][0] != 0)
        sc.apply(*cmds)


def test_world_view_from_the_wire_gives_the_same_commands(road) -> None:
    # the node graph's SUT decides on a WorldView rebuilt from the world table
    w = blocked_left(road)
    cfg = cfg_for("mobil", "blind_behind")
    a = create_driver("mutant", "sut", EGO, cfg, np.random.default_rng(3))
    b = create_driver("mutant", "sut", EGO, cfg, np.random.default_rng(3))
    wv = WorldView(road, {k: np.array(v) for k, v in w.columns().items()}, w.step_index, w.dt_s)
    ta, ca = a.act(w)
    tb, cb = b.act(wv)
    assert np.array_equal(ta, tb) and np.array_equal(ca, cb)


def test_inprocess_run_of_a_mutant_completes(tmp_path: Path) -> None:
    cfg = load_scenario_config(None, mutant_overrides("mobil", "stale"))
    summary = run_inprocess(cfg, bag_dir=None, steps=300)
    assert summary is not None


# ------------------------------------------------------------------ configuration and library
def test_yaml_declares_a_mutant(tmp_path: Path) -> None:
    f = tmp_path / "mut.yaml"
    f.write_text("sut:\n  model: mutant\nmodels:\n  mutant:\n    base: nilsson\n    operator: weak_braking\n"
                 "    brake_factor: 0.5\n  nilsson:\n    hysteresis: 0.5\n", encoding="utf-8")
    cfg = load_scenario_config(f)
    drv = build_sut_driver(cfg)
    assert isinstance(drv, M.MutantDriver) and drv.params.brake_factor == 0.5
    assert drv.base.params.hysteresis == 0.5  # the base's own section is used


@pytest.mark.parametrize(("key", "value", "msg"), [
    ("base", "mutant", r"models\.mutant\.base.*expected one of"),
    ("base", "nosuch", r"models\.mutant\.base.*expected one of"),
    ("operator", "blind", r"models\.mutant\.operator.*expected one of"),
    ("delay_steps", "0", r"models\.mutant\.delay_steps"),
])
def test_bad_mutant_config_is_one_line_error(key: str, value: str, msg: str) -> None:
    over = {"sut.model": "mutant", "models.mutant.base": "mobil", "models.mutant.operator": "stale"}
    over[f"models.mutant.{key}"] = value
    with pytest.raises(InputError, match=msg) as exc:
        load_scenario_config(None, over)
    assert "\n" not in str(exc.value)


def test_factory_rejects_a_bad_base_given_directly(base_cfg) -> None:
    with pytest.raises(InputError, match=r"^models\.mutant\.base 'mutant'"):
        M.make_driver(np.array([0]), M.MutantParams(base="mutant"), base_cfg, np.random.default_rng(0))


def test_library_and_overrides() -> None:
    assert len(LIBRARY) >= 9
    for klass in ("perception", "decision", "control"):
        assert sum(m.klass == klass for m in LIBRARY.values()) >= 2
    assert all(isinstance(m, Mutant) and m.description for m in LIBRARY.values())
    over = mutant_overrides("mobil", "reaction_time")
    assert over == {"sut.model": "mutant", "models.mutant.base": "mobil",
                    "models.mutant.operator": "reaction_time", "models.mutant.delay_steps": "10"}
    with pytest.raises(InputError, match="mutant 'nosuch'"):
        mutant_overrides("mobil", "nosuch")
    for base in ("mobil", "nilsson", "stackelberg"):
        for name, m in LIBRARY.items():
            cfg = load_scenario_config(None, mutant_overrides(base, name))
            drv = build_sut_driver(cfg)
            assert drv.params.operator == m.operator and drv.params.base == base
            for k, v in m.params.items():
                assert getattr(drv.params, k) == v


# ------------------------------------------------------------------ views without whole-table copies
def _copied_view(view, ego, rows, source=None, s_shift=None):
    """The filtered view by its definition: every column copied, then the rows taken (a WorldView)."""
    own = M.view_columns(view)
    src = own if source is None else source
    cols = {c: np.concatenate([own[c][ego:ego + 1], src[c][np.asarray(rows, dtype=np.int64)]]) for c in M._COLUMNS}
    if s_shift is not None:
        cols["s"][1:] += s_shift
    return WorldView(view.road, cols, view.step_index, view.dt_s)


def _same_view(a, b) -> None:
    for attr in ("ids", "role", "policy", "s", "d", "psi", "v", "accel", "steer", "lane", "target_lane",
                 "lane_change", "length", "width", "speed_limit_mps"):
        x, y = getattr(a, attr), getattr(b, attr)
        assert x.dtype == y.dtype and np.array_equal(x, y, equal_nan=True), attr
    na, nb = a.neighborhood(), b.neighborhood()
    for f in ("leader", "follower", "gap_front_m", "gap_rear_m", "leader_speed_mps", "follower_speed_mps"):
        assert np.array_equal(getattr(na, f), getattr(nb, f), equal_nan=True), f
    assert (a.n, a.step_index, a.dt_s) == (b.n, b.step_index, b.dt_s)


def test_subview_is_the_copied_view_row_for_row(road) -> None:
    # ego 1 of 5, vehicle 0 on the merge lane (which exists from s = 600 m to about 1,000 m): filtered
    # rows, rows moved by a shift (looked up again at their new s), rows of a remembered source
    w = hand_built_world(road, s=[650.0, 700.0, 730.0, 685.0, 820.0], lane=[0, 1, 1, 2, 1],
                         speed=[20.0, 25.0, 20.0, 35.0, 30.0])
    rows = np.array([0, 2, 4])
    _same_view(M.subview(w, 1, rows), _copied_view(w, 1, rows))
    shift = np.array([400.0, 15.0, 0.0])
    moved = M.subview(w, 1, rows, s_shift=shift)
    _same_view(moved, _copied_view(w, 1, rows, s_shift=shift))
    assert np.isnan(moved.speed_limit_mps[1]) and moved.speed_limit_mps[0] == pytest.approx(120 / 3.6)  # no lane 0
    old = M.view_columns(w)
    old["s"] = old["s"] - 7.0
    _same_view(M.subview(w, 1, np.array([3, 0]), source=old), _copied_view(w, 1, [3, 0], source=old))
    old["speed_limit_mps"] = np.full(w.n, 12.5)  # a source's own limits are taken as they are
    assert M.subview(w, 1, np.array([3, 0]), source=old).speed_limit_mps.tolist()[1:] == [12.5, 12.5]


def test_subview_of_everything_in_order_is_the_view_itself(road) -> None:
    w = blocked_left(road)
    assert M.subview(w, 0, np.array([1, 2])) is w
    assert M.subview(w, 0, np.array([2, 1])) is not w  # another order: a view of its own
    assert M.subview(w, 0, np.array([1, 2]), s_shift=np.zeros(2)) is not w


@pytest.mark.parametrize("operator", ["tailgating", "ignores_new_follower"])
def test_two_view_operators_draw_and_decide_as_two_full_drivers(road, operator) -> None:
    # throttle from one base driver, lane change from the twin: the same commands and the same
    # state of the scenario's generator as running act() of both on their views
    w = hand_built_world(road, s=[300.0, 324.8, 290.0, 340.0], lane=[1, 1, 2, 2], speed=[25.0, 22.0, 30.0, 25.0])
    cfg = cfg_for("mobil", operator)
    m = create_driver("mutant", "sut", EGO, cfg, np.random.default_rng(4))
    ref = create_driver("mutant", "sut", EGO, cfg, np.random.default_rng(4))
    for _ in range(3):
        view_t = ref._tailgate(w) if operator == "tailgating" else ref.perceived(w)
        view_c = ref.perceived(w) if operator == "tailgating" else ref._without_new_followers(w)
        want_t, want_c = ref.base.act(view_t)[0], ref.decider.act(view_c)[1]
        got_t, got_c = m.act(w)
        assert np.array_equal(got_t, want_t) and np.array_equal(got_c, want_c)
    assert m.base.krauss.rng.random() == ref.base.krauss.rng.random()
