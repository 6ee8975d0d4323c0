"""SUT mutants: an intact SUT model with one deliberate, documented defect (docs/method.md §7; docs/mutants.md).

The model ``mutant`` (role ``sut``) wraps the driver of any registered SUT model — a built-in
or a user's ``evoscen.sut`` plug-in — named by ``models.mutant.base``, and degrades it with one
*operator* (``models.mutant.operator``)::

    sut:
      model: mutant
    models:
      mutant: {base: mobil, operator: blind_behind}

Operators (parameters in brackets; see docs/mutants.md for the reasons of the defaults):

* perception — the base driver decides on a *filtered view*: a
  :class:`evoscen_sim.loop.view.WorldView` holding the SUT in row 0 and the other vehicles it
  perceives after it, in their world order; the base driver is built for row 0.

  - ``blind_behind``: vehicles whose centre is behind the SUT's (all lanes) are invisible.
  - ``short_view`` [``view_m``]: vehicles more than ``view_m`` ahead (centre distance) are invisible.
  - ``stale`` [``delay_steps``]: the other vehicles are seen as they were ``delay_steps`` steps
    ago (the SUT's own state is current).

* decision —

  - ``ignores_new_follower``: the lane-change request is decided on a view without the
    vehicles behind the SUT in the two adjacent lanes; the throttle on the full view.
  - ``late_lane_change`` [``delay_steps``]: a lane-change request is executed ``delay_steps``
    steps after it was decided (the throttle is current; no request in the first
    ``delay_steps`` steps).
  - ``over_eager`` [``retune``]: the base model's own parameters re-tuned to change lanes
    eagerly (:data:`EAGER_PRESETS` for ``mobil``, ``nilsson``, ``stackelberg``; for any model,
    ``retune: "name=value, ..."`` names parameters of ``models.<base>`` to replace).
  - ``timid`` [``speed_factor``]: the base's desired speed multiplied by ``speed_factor`` (its
    desired-speed parameters, :func:`timid_parameters`): the SUT gives away progress the traffic
    allows.
  - ``frozen``: no discretionary lane change — the base's lane-change requests pass only while
    the SUT is on a lane that ends ahead (the merge lane: the mandatory merge); elsewhere none.

* control —

  - ``reaction_time`` [``delay_steps``]: both commands pass a delay line of ``delay_steps`` steps
    (filled at the start with the first throttle and no lane change).
  - ``weak_braking`` [``brake_factor``]: braking commands (throttle < 0) scaled by ``brake_factor``.
  - ``late_braking`` [``brake_onset``]: braking weaker than ``brake_onset`` (throttle in
    (−brake_onset, 0)) is not applied (coasting), so braking starts later and harder.
  - ``tailgating`` [``extra_gap_m``]: for the throttle, every vehicle ahead in the own lane
    appears ``extra_gap_m`` farther than it is, so the car follower closes up; the
    lane-change decision sees the true traffic.

Where the throttle and the lane change come from different views (``ignores_new_follower``,
``tailgating``) the mutant runs two instances of the base driver, the second with a copy of the
random generator taken at construction: both draw the same numbers, so the throttle path
consumes the scenario's ``sut`` stream exactly as the intact model does.

Determinism: the only random draws are the base driver's, from the ``rng`` passed in; the
delay lines and snapshots are per driver instance.
"""

from __future__ import annotations

import copy
import dataclasses
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np
import yaml
from evoscen_sim import model_registry as _models
from evoscen_sim.config.scenario_config import integer, number, text
from evoscen_sim.errors import InputError
from evoscen_sim.model_registry import ModelSpec, get_model, model_names
from evoscen_sim.physics.window import common_shift
from evoscen_sim.road.road_kernels import lane_end_distance
from evoscen_sim.loop.view import WorldView

from .krauss_lane_change import KraussLaneChangeDriver

NAME = "mutant"

PERCEPTION = ("blind_behind", "short_view", "stale")
DECISION = ("ignores_new_follower", "late_lane_change", "over_eager", "timid", "frozen")
CONTROL = ("reaction_time", "weak_braking", "late_braking", "tailgating")
OPERATORS = PERCEPTION + DECISION + CONTROL
"""Every operator, by class: perception, decision, control."""

EAGER_PRESETS: dict[str, dict[str, Any]] = {
    "mobil": {"threshold_mps2": 0.0, "bias_mps2": 0.0, "safe_decel_mps2": 9.0},
    "nilsson": {"hysteresis": 0.0, "keep_right_bias": 0.0, "safety_length_factor": 1.0,
                "safety_closing_headway_s": 0.0},
    "stackelberg": {"lane_change_threshold_m": 0.0, "time_headway_s": 0.0, "min_gap_m": 0.0},
}
"""``over_eager`` re-tunings of the built-in models (docs/mutants.md): no incentive threshold or
hysteresis, no keep-right bias, and the safety margin towards the new follower cut to what
only an emergency manoeuvre can honour (MOBIL b_safe 9 m/s² ≈ full braking; Nilsson's
safety distance one ego length, no closing-speed term; Stackelberg's U_neg without headway
and minimum gap)."""


def _base_choices() -> tuple[str, ...]:
    return tuple(n for n in _models.SUT_MODELS if n != NAME)


@dataclass(frozen=True)
class MutantParams:
    """The ``mutant`` model's parameters (``models.mutant``; docs/mutants.md)."""

    base: str = text("mobil", _base_choices)
    """The intact SUT model (any registered SUT model but ``mutant``). Its own parameters are
    ``models.<base>`` as usual."""
    operator: str = text("blind_behind", OPERATORS)
    """The defect, one of :data:`OPERATORS`."""
    view_m: float = number(50.0, 0.0, 10000.0, lo_open=True)
    """``short_view``: perception range ahead (m, centre distance). Default 50 m: the visibility
    at which fog forces 50 km/h on German roads (StVO §3(1)), a sensor range well below the
    ~100–150 m the intact models look ahead."""
    delay_steps: int = integer(10, 1, 1000)
    """``stale``, ``late_lane_change``, ``reaction_time``: delay in simulation steps. Default 10
    (1 s at 0.1 s): a human-like reaction time, several times an automated system's latency."""
    brake_factor: float = number(0.4, 0.0, 1.0)
    """``weak_braking``: braking commands are multiplied by this. Default 0.4 (worn brakes or a
    controller that saturates at 40 % of the braking it asks for)."""
    brake_onset: float = number(0.25, 0.0, 1.0, lo_open=True)
    """``late_braking``: braking commands weaker than this (throttle in (−onset, 0)) are
    dropped. Default 0.25, i.e. 2 m/s² with the default 8 m/s² full brake: gentle anticipatory
    braking disappears."""
    extra_gap_m: float = number(15.0, 0.0, 500.0)
    """``tailgating``: the vehicles ahead in the own lane appear this much farther (m). Default
    15 m: the Krauss follower's ~1 s headway at highway speed (25–33 m/s) shrinks to ~0.5 s."""
    speed_factor: float = number(0.6, 0.0, 1.0, lo_open=True)
    """``timid``: the base's desired speed is multiplied by this. Default 0.6: a driver at 60 % of
    the speed it was built for (72 km/h where the built-in models want 120 km/h), far below the
    mainline's 90 km/h minimum (docs/mutants.md)."""
    retune: str = text("preset")
    """``over_eager``: ``preset`` (:data:`EAGER_PRESETS` of the base model) or
    ``"name=value, ..."``: parameters of ``models.<base>`` to replace (applied on top of the
    preset, if the base has one)."""


# ------------------------------------------------------------------------------- views
_COLUMNS = ("id", "role", "policy", "s", "d", "heading_rel", "speed", "accel", "steer", "lane",
            "target_lane", "lane_change", "length", "width")


def view_columns(view: Any) -> dict[str, np.ndarray]:
    """The world-table columns a :class:`WorldView` needs, copied from any traffic view."""
    return {
        "id": np.array(view.ids), "role": np.array(view.role), "policy": np.array(view.policy),
        "s": np.array(view.s, dtype=float), "d": np.array(view.d, dtype=float),
        "heading_rel": np.array(view.psi, dtype=float), "speed": np.array(view.v, dtype=float),
        "accel": np.array(view.accel, dtype=float), "steer": np.array(view.steer, dtype=float),
        "lane": np.array(view.lane), "target_lane": np.array(view.target_lane),
        "lane_change": np.array(view.lane_change), "length": np.array(view.length, dtype=float),
        "width": np.array(view.width, dtype=float),
    }


_ATTRS = {"id": "ids", "role": "role", "policy": "policy", "s": "s", "d": "d", "heading_rel": "psi", "speed": "v",
          "accel": "accel", "steer": "steer", "lane": "lane", "target_lane": "target_lane",
          "lane_change": "lane_change", "length": "length", "width": "width"}
"""World-table column -> the view attribute it fills (:class:`WorldView`)."""
_INTS = frozenset(("id", "role", "policy", "lane", "target_lane", "lane_change"))


class RowView(WorldView):
    """A :class:`WorldView` of selected rows: each column taken with one index from its source
    (no copy of the whole table first; docs/performance.md "Per-step work of the SUT drivers").
    Road look-ups and the neighbourhood are computed for these rows, as for any view."""

    def __init__(self, road: Any, columns: dict[str, np.ndarray], step_index: int, dt_s: float,
                 speed_limit_mps: np.ndarray | None = None) -> None:
        # the columns are fresh arrays of the right dtypes (:func:`subview`): no checks, no copies;
        # ``speed_limit_mps``: the rows' limits where known (each row's own road look-up)
        self.road = road
        self.dt_s = float(dt_s)
        self.step_index = int(step_index)
        self.ids, self.role, self.policy = columns["id"], columns["role"], columns["policy"]
        self.lane, self.target_lane, self.lane_change = columns["lane"], columns["target_lane"], columns["lane_change"]
        self.s, self.d, self.psi, self.v = columns["s"], columns["d"], columns["heading_rel"], columns["speed"]
        self.accel, self.steer, self.length, self.width = (columns["accel"], columns["steer"], columns["length"],
                                                           columns["width"])
        self.n = int(self.s.shape[0])
        self._neighborhood = None
        self._speed_limit = speed_limit_mps
        self._lanes = None


_ATTR_DTYPES = tuple((col, attr, np.int64 if col in _INTS else np.float64) for col, attr in _ATTRS.items())


def _rows_of(view: Any, rows: np.ndarray) -> dict[str, np.ndarray]:
    """The columns of ``view``'s ``rows`` (fresh arrays), as :func:`view_columns` then :class:`WorldView`
    would make them (ints as int64, floats as float64)."""
    out = {}
    for col, attr, dtype in _ATTR_DTYPES:
        x = getattr(view, attr)
        x = x[rows] if type(x) is np.ndarray else np.asarray(x)[rows]
        out[col] = x if x.dtype == dtype else x.astype(dtype)
    return out


def _speed_limits(view: Any, rows: np.ndarray) -> np.ndarray:
    """The speed limits of ``view``'s ``rows`` (its own, computed once per state)."""
    return np.asarray(view.speed_limit_mps, dtype=float)[rows]


def subview(view: Any, ego: int, others: np.ndarray, *, source: dict[str, np.ndarray] | None = None,
            s_shift: np.ndarray | None = None) -> Any:
    """A view with the ego (row ``ego`` of ``view``) in row 0, then the rows ``others`` of
    ``source`` (default: ``view``'s columns) in their order; ``s_shift`` (per row of ``others``)
    is added to those vehicles' ``s``.

    The same numbers as a :class:`WorldView` of the copied columns (docs/performance.md "Per-step
    work of the SUT drivers"): when that would be ``view`` itself in its own order (the ego in row 0,
    every other vehicle after it in order, no shift, no other source) it is ``view``, whose road
    look-ups and neighbourhood are computed already; otherwise each row keeps its speed limit from
    ``view`` (or from ``source["speed_limit_mps"]`` where the source has it), the road look-up of a
    row being its own: only the rows moved by ``s_shift`` are looked up again."""
    rows = np.asarray(others, dtype=np.int64)
    if (source is None and s_shift is None and ego == 0 and rows.shape[0] == view.n - 1
            and bool((rows == np.arange(1, view.n)).all())):
        return view
    if source is None:
        take = np.concatenate((np.array([ego], dtype=np.int64), rows))
        cols = _rows_of(view, take)
        limit = _speed_limits(view, take)
    else:
        own = _rows_of(view, np.array([ego], dtype=np.int64))
        cols = {}
        for c in _COLUMNS:
            x = np.concatenate([own[c], source[c][rows]])
            cols[c] = x.astype(np.int64, copy=False) if c in _INTS else x
        known = source.get("speed_limit_mps")
        limit = None if known is None else np.concatenate([_speed_limits(view, np.array([ego])), known[rows]])
    if s_shift is not None:
        cols["s"][1:] += s_shift
        moved = np.flatnonzero(np.asarray(s_shift) != 0.0) + 1
        if limit is not None and moved.size:
            lanes = view.road.lane_lookup(np.maximum(cols["s"][moved], 0.0), cols["d"][moved])
            limit[moved] = lanes.max_speed_mps[np.arange(moved.size), cols["lane"][moved]]
    return RowView(view.road, cols, view.step_index, view.dt_s, limit)


_OTHERS: dict[tuple[int, int], np.ndarray] = {}


def _others(view: Any, ego: int) -> np.ndarray:
    """The rows of ``view`` but ``ego``, in order (made once per vehicle count and ego, read-only: the
    callers index with it, never write it)."""
    key = (int(view.n), int(ego))
    out = _OTHERS.get(key)
    if out is None:
        idx = np.arange(key[0])
        out = idx[idx != key[1]]
        out.flags.writeable = False
        if len(_OTHERS) >= 256:
            _OTHERS.clear()
        _OTHERS[key] = out
    return out


# ------------------------------------------------------------------------------- driver
class MutantDriver:
    """A base SUT driver with one defect (module docstring). Drives exactly one vehicle.

    Args:
        params: the :class:`MutantParams`.
        ego: the SUT's world index.
        make_base: ``make_base(vehicles, rng) -> driver`` builds an instance of the base driver.
        rng: the scenario's SUT random generator (handed to the base driver).
    """

    def __init__(self, params: MutantParams, ego: int, make_base: Any, rng: np.random.Generator) -> None:
        self.params = params
        self.ego = int(ego)
        self.vehicles = np.array([self.ego], dtype=np.int64)
        op = params.operator
        self._filtered = op in PERCEPTION or op in ("ignores_new_follower", "tailgating")
        two = op in ("ignores_new_follower", "tailgating")
        twin_rng = copy.deepcopy(rng) if two else None  # before the base driver draws anything
        self.base = make_base(np.array([0]) if self._filtered else self.vehicles, rng)
        self.decider = make_base(np.array([0]), twin_rng) if two else None
        self._snapshots: deque[dict[str, np.ndarray]] = deque(maxlen=params.delay_steps + 1)
        self._commands: deque[tuple[np.ndarray, np.ndarray]] = deque(maxlen=params.delay_steps + 1)
        self._requests: deque[np.ndarray] = deque(maxlen=params.delay_steps + 1)

    # -- the views of the perception and decision operators
    def perceived(self, view: Any) -> Any:
        """The view the base driver perceives (perception operators), the full view otherwise."""
        ego, op = self.ego, self.params.operator
        others = _others(view, ego)
        if op == "blind_behind":
            return subview(view, ego, others[view.s[others] >= view.s[ego]])
        if op == "short_view":
            return subview(view, ego, others[view.s[others] - view.s[ego] <= self.params.view_m])
        if op == "stale":
            now = view_columns(view)
            now["speed_limit_mps"] = _speed_limits(view, np.arange(view.n))  # a copy: the rows' own
            if self._snapshots:  # a window shift moved every vehicle: the remembered states move too
                shift = common_shift(self._snapshots[-1]["s"], now["s"])
                if shift:
                    for old in self._snapshots:
                        old["s"] = old["s"] + shift
                        old.pop("speed_limit_mps", None)  # looked up again where the vehicles are now
            self._snapshots.append(now)
            old = self._snapshots[0]  # delay_steps ago, or the oldest seen
            ego_id = view.ids[ego]
            rows = np.flatnonzero(old["id"] != ego_id)
            return subview(view, ego, rows, source=old)
        return subview(view, ego, others)

    def _without_new_followers(self, view: Any) -> Any:
        ego = self.ego
        others = _others(view, ego)
        beside = np.abs(view.lane[others] - view.lane[ego]) == 1
        behind = view.s[others] < view.s[ego]
        return subview(view, ego, others[~(beside & behind)])

    def _tailgate(self, view: Any) -> Any:
        ego = self.ego
        others = _others(view, ego)
        ahead = (view.lane[others] == view.lane[ego]) & (view.s[others] > view.s[ego])
        return subview(view, ego, others, s_shift=np.where(ahead, self.params.extra_gap_m, 0.0))

    def _on_ending_lane(self, view: Any) -> bool:
        """The SUT is on a lane that ends ahead (the merge lane): changing out of it is mandatory."""
        ego = self.ego  # road.distance_to_lane_end, compiled (inf where numpy's is NaN: neither is finite)
        return bool(np.isfinite(lane_end_distance(view.road.kernel_tables(), int(view.lane[ego]), float(view.s[ego]))))

    @staticmethod
    def _throttle(driver: Any, view: Any) -> np.ndarray:
        """``driver.act(view)[0]``; a :class:`KraussLaneChangeDriver` computes the throttle alone (the
        same numbers and random draws; docs/performance.md "Per-step work of the SUT drivers")."""
        if isinstance(driver, KraussLaneChangeDriver):
            return driver.throttle(view)
        return driver.act(view)[0]

    @staticmethod
    def _lane_change(driver: Any, view: Any) -> np.ndarray:
        """``driver.act(view)[1]``; a :class:`KraussLaneChangeDriver` decides alone: the throttle it
        would also compute draws only from the twin's own copy of the random generator, which
        nothing else reads."""
        if isinstance(driver, KraussLaneChangeDriver):
            return driver.lane_change(view)
        return driver.act(view)[1]

    def act(self, view: Any) -> tuple[np.ndarray, np.ndarray]:
        """Throttle in [-1, 1] and lane-change request in {-1, 0, +1} of the SUT."""
        p, op = self.params, self.params.operator
        if op == "ignores_new_follower":
            throttle = np.asarray(self._throttle(self.base, self.perceived(view)), dtype=float)
            lane_change = np.asarray(self._lane_change(self.decider, self._without_new_followers(view)))
        elif op == "tailgating":
            throttle = np.asarray(self._throttle(self.base, self._tailgate(view)), dtype=float)
            lane_change = np.asarray(self._lane_change(self.decider, self.perceived(view)))
        else:
            throttle, lane_change = self.base.act(self.perceived(view) if self._filtered else view)
            throttle = np.asarray(throttle, dtype=float)
            lane_change = np.asarray(lane_change)
        if op == "late_lane_change":
            if not self._requests:  # before the first decision: no request
                self._requests.extend([np.zeros_like(lane_change)] * p.delay_steps)
            self._requests.append(lane_change.copy())
            lane_change = self._requests[0].copy()
        elif op == "reaction_time":
            if not self._commands:  # before the first command: the first throttle, no lane change
                self._commands.extend([(throttle.copy(), np.zeros_like(lane_change))] * p.delay_steps)
            self._commands.append((throttle.copy(), lane_change.copy()))
            throttle, lane_change = (x.copy() for x in self._commands[0])
        elif op == "frozen":
            lane_change = np.where(self._on_ending_lane(view), lane_change, 0)
        elif op == "weak_braking":
            throttle = np.where(throttle < 0.0, throttle * p.brake_factor, throttle)
        elif op == "late_braking":
            throttle = np.where((throttle < 0.0) & (throttle > -p.brake_onset), 0.0, throttle)
        return throttle, lane_change.astype(np.int64)


# ------------------------------------------------------------------------------- factory
def _retuned(base: str, base_params: Any, retune: str) -> Any:
    """The base parameters with the ``over_eager`` re-tuning (InputError naming the key)."""
    key = "models.mutant.retune"
    changes = dict(EAGER_PRESETS.get(base, {}))
    if retune != "preset":
        for item in (x.strip() for x in retune.split(",")):
            if not item:
                continue
            name, sep, raw = item.partition("=")
            if not sep:
                raise InputError(f"{key} = '{retune}': expected 'preset' or 'name=value, ...'")
            changes[name.strip()] = yaml.safe_load(raw.strip())
    if base_params is None or not dataclasses.is_dataclass(base_params):
        raise InputError(f"{key}: base model '{base}' has no parameters to re-tune")
    if not changes:
        raise InputError(f"{key} = '{retune}': base model '{base}' has no built-in over-eager preset "
                         "(presets: " + ", ".join(EAGER_PRESETS) + "); expected 'name=value, ...'")
    fields = {f.name: f for f in dataclasses.fields(base_params)}
    checked: dict[str, Any] = {}
    for name, value in changes.items():
        f = fields.get(name)
        if f is None:
            raise InputError(f"{key}: '{name}' is not a parameter of models.{base} "
                             f"(expected one of {', '.join(fields)})")
        check = f.metadata.get("check")
        if check is not None:
            try:
                value = check(value)
            except Exception as exc:  # noqa: BLE001 - the checker's own message
                raise InputError(f"{key}: models.{base}.{name} = {value!r}: {exc}") from None
        checked[name] = value
    return dataclasses.replace(base_params, **checked)


KRAUSS_BASES = ("mobil", "nilsson", "stackelberg")
"""Built-in SUT models whose car following is the scenario's Krauss model (``models.krauss``):
``timid`` scales its desired speed too."""
SPEED_FIELDS = ("desired_speed_mps", "speed_factor")
"""Parameters of ``models.<base>`` that set a desired speed (a speed, or a multiple of the speed
limit as ``sumo_sut``'s ``speed_factor``): ``timid`` scales each one the base has."""


def _replaced(obj: Any, **changes: Any) -> Any:
    """``obj`` with ``changes`` (a dataclass through :func:`dataclasses.replace`, else a shallow copy)."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return dataclasses.replace(obj, **changes)
    out = copy.copy(obj)
    for key, value in changes.items():
        setattr(out, key, value)
    return out


def timid_parameters(base: str, base_params: Any, config: Any, factor: float) -> tuple[Any, Any, list[str]]:
    """The base's parameters and the scenario with every desired speed of the base multiplied by
    ``factor`` (``timid``), and the keys changed: each of :data:`SPEED_FIELDS` its parameters have,
    ``models.krauss.desired_speed_mps`` for :data:`KRAUSS_BASES` (the configuration handed to the
    base only: the BVs keep theirs), ``level0.desired_speed_mps`` (the range) for ``level0``.
    InputError (one line) for a base without a desired speed evoscen knows."""
    changed: list[str] = []
    if base_params is not None and dataclasses.is_dataclass(base_params):
        names = {f.name for f in dataclasses.fields(base_params)}
        updates = {n: getattr(base_params, n) * factor for n in SPEED_FIELDS if n in names}
        if updates:
            base_params = dataclasses.replace(base_params, **updates)
            changed += [f"models.{base}.{n}" for n in updates]
    if base in KRAUSS_BASES:
        from .krauss import NAME as KRAUSS, krauss_params_from_config

        kp = krauss_params_from_config(config)
        models = dict(getattr(config, "models", None) or {})
        models[KRAUSS] = dataclasses.replace(kp, desired_speed_mps=kp.desired_speed_mps * factor)
        config = _replaced(config, models=models)
        changed.append(f"models.{KRAUSS}.desired_speed_mps")
    if base == "level0":
        lo, hi = config.level0.desired_speed_mps
        config = _replaced(config, level0=_replaced(config.level0, desired_speed_mps=(lo * factor, hi * factor)))
        changed.append("level0.desired_speed_mps")
    if not changed:
        raise InputError(f"models.mutant.operator 'timid': base model '{base}' has no desired speed to scale "
                         f"(expected a parameter {' or '.join(SPEED_FIELDS)} in models.{base})")
    return base_params, config, changed


def make_driver(vehicles: np.ndarray, params: MutantParams | None, config: Any,
                rng: np.random.Generator) -> MutantDriver:
    """Factory of the ``mutant`` model (:class:`evoscen_sim.model_registry.ModelSpec`)."""
    params = MutantParams() if params is None else params
    if params.base == NAME or params.base not in model_names("sut"):
        raise InputError(f"models.mutant.base '{params.base}': expected one of "
                         + ", ".join(n for n in model_names("sut") if n != NAME))
    vehicles = np.asarray(vehicles, dtype=np.int64)
    if vehicles.shape != (1,):
        raise InputError(f"model 'mutant' drives one vehicle (the SUT), got {vehicles.size}")
    spec = get_model(params.base, "sut")
    base_params = None
    if spec.params_type is not None:
        base_params = config.models.get(params.base) if hasattr(config, "models") else None
        if base_params is None:
            base_params = spec.params_type()
    if params.operator == "over_eager":
        base_params = _retuned(params.base, base_params, params.retune)
    if params.operator == "timid":
        base_params, config, _ = timid_parameters(params.base, base_params, config, params.speed_factor)

    def make_base(rows: np.ndarray, generator: np.random.Generator) -> Any:
        return spec.factory(np.asarray(rows, dtype=np.int64), base_params, config, generator)

    return MutantDriver(params, int(vehicles[0]), make_base, rng)


SPEC = ModelSpec(name=NAME, roles=("sut",), factory=make_driver, params_type=MutantParams,
                 description="a registered SUT model with one deliberate defect (docs/method.md §7, docs/mutants.md)")
