"""A run as arrays: what the scores, the report and the fidelity extraction read.

One accumulator, three feeders, so the live evaluator, an offline evaluation of the bag and
the in-process runner see *the same numbers* (and, scoring, compute them in one pass,
:mod:`evoscen_eval.scoring.streaming`):

* the evaluator node feeds it the serialized messages it records (:meth:`RunAccumulator.add_bytes`);
* :func:`read_run` (the run as arrays) and :func:`score_bag` (the scores in one pass) feed it
  the messages of a bag, in file order (a truncated or corrupt bag: the readable prefix, with
  a warning saying how many states were read);
* the in-process runner feeds it the world's columns and the event dicts directly (the world
  table's float64 values are exactly the columns; event values survive the KeyValue strings
  exactly: ints, ``repr`` floats).

The resolved scenario configuration travels in the bag as an MCAP metadata record
(:mod:`evoscen_record.scenario_record`, written first, before any message), so a bag alone is
enough to evaluate a run with the settings it ran with.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from evoscen_contract import contract as C
from evoscen_contract.cdr import TableDecodeError, decode_table, events_count
from evoscen_record.scenario_record import EXTERNAL_SUT, SCENARIO_KEY, SCENARIO_METADATA, SUT_SOURCE_KEY
from evoscen_sim.limits import MAX_STEPS
from evoscen_sim.config.scenario_config import EvaluationConfig, evaluation_from_dict
from evoscen_sim.errors import InputError


@dataclass
class RunData:
    """One run, state by state.

    ``columns[name]`` is a float64 ``[K, V]`` array for every name of
    :data:`evoscen_contract.contract.WORLD_FIELDS`: row k = the world state at ``time_s[k]``,
    column v = one vehicle (the world table's row order, constant through a run).
    """

    time_s: np.ndarray
    columns: dict[str, np.ndarray]
    ids: np.ndarray
    sut_index: int
    events: list[dict]
    dt_s: float
    scenario: dict | None = None
    complete: bool = False
    warnings: list[str] = field(default_factory=list)
    external_sut: bool = False
    """The SUT was a user's node (``--external-sut``), not the scenario's ``sut.model``."""
    lane_segments: np.ndarray | None = None
    """Lane lines and road edges as ``[M, 2, 2]`` map-frame segments (from the map markers)."""

    @property
    def states(self) -> int:
        """Number of recorded world states K (a run of N steps has N + 1)."""
        return int(self.time_s.shape[0])

    def events_named(self, name: str, kind: str | None = None) -> list[dict]:
        """The events called ``name`` (and of ``kind``, if given), in order."""
        return [e for e in self.events if e["name"] == name and (kind is None or e.get("kind") == kind)]


class RunAccumulator:
    """Collects world states, events and the map of a run (see the module docstring).

    With ``keep_world`` (default) it holds the run (:meth:`run_data`: the ``[K, V]`` columns
    the fidelity extraction and the realism figures read). For scoring alone, ``keep_world=False``
    and :meth:`start_scoring` before the first state: each state goes to a
    :class:`~evoscen_eval.scoring.streaming.ScoreStream` and is not kept, so scoring memory does not
    grow with the run (the live evaluator, the in-process runner, ``scripts/evaluate.py``).
    """

    def __init__(self, expected_states: int | None = None, *, keep_world: bool = True) -> None:
        # The world states live in one float64 buffer [F, capacity, V]: field j of states 0..K-1
        # is the contiguous block buf[j, :K], which RunData.columns hands out as views, so the
        # [K, V] columns are held once (before: a list of [V, F] arrays, then np.stack, then a
        # contiguous copy per field: three copies at scoring). ``expected_states`` (a run of N
        # steps has N + 1) sizes the buffer exactly; without it, or beyond it, it doubles.
        self._expected = max(1, int(expected_states)) if expected_states else 1024
        self._buf: np.ndarray | None = None
        self._k = 0
        self._times_ns: list[int] = []
        self.events: list[dict] = []
        self.complete = False
        self.lane_segments: np.ndarray | None = None
        self._events_class: Any = None
        self._markers_class: Any = None
        self.keep_world = keep_world
        self.stream: Any = None
        self._last_table: np.ndarray | None = None
        self._last_stamp: int | None = None

    def start_scoring(self, ev: Any, dt_s: float | None = None, *, frames: bool = True) -> Any:
        """Score the states as they come (a :class:`~evoscen_eval.scoring.streaming.ScoreStream` under
        ``ev``, step ``dt_s`` or from the stamps; ``frames``: collect the animation's frames); before the
        first world state."""
        from evoscen_eval.scoring.streaming import ScoreStream

        if self._k:
            raise ValueError("scoring must start before the first world state")
        self.stream = ScoreStream(ev, dt_s, frames=frames)
        self.stream.add_events(self.events)
        if not self.keep_world:
            self.events = [e for e in self.events if e["name"] == C.EVENT_RUN_END]
        return self.stream

    # ------------------------------------------------------------------ feeding

    def expect(self, states: int) -> None:
        """Size the buffer for ``states`` world states (before the first one arrives)."""
        if self._buf is None and 1 <= states <= 1 + MAX_STEPS:
            self._expected = int(states)

    def add_world_columns(self, columns: Mapping[str, np.ndarray], t_ns: int) -> None:
        """A world state from the world's columns (copied)."""
        # the fields stacked as rows, then transposed: the same float64 values as np.column_stack of
        # them at a fifth of its cost (docs/performance.md "Per-step work of the scores")
        fields = C.WORLD_FIELDS
        rows = np.array([columns[f] for f in fields], dtype=np.float64)
        if rows.ndim != 2:
            raise ValueError(f"world columns: expected one value per vehicle in each, got shape {rows.shape}")
        table = rows.T.copy()
        self._add_state(table, t_ns)

    def add_world_table(self, table: np.ndarray, t_ns: int) -> None:
        """A world state as the world table's rows ``[V, F]`` (float64, the contract's columns; kept, not copied:
        :meth:`evoscen_sim.physics.world.World.table` makes a fresh one per state)."""
        if table.ndim != 2 or table.shape[1] != len(C.WORLD_FIELDS) or table.dtype != np.float64:
            raise ValueError(f"world table: expected float64 rows of {len(C.WORLD_FIELDS)} columns, got "
                             f"{table.dtype} of shape {table.shape}")
        self._add_state(table, t_ns)

    def add_events(self, events: Iterable[Mapping[str, Any]]) -> None:
        """Event dicts of one ``/evoscen/events`` message."""
        for event in events:
            if self.keep_world or self.stream is None:
                self.events.append(dict(event))
            if event["name"] == C.EVENT_RUN_END:
                self.complete = True
        if self.stream is not None:
            self.stream.add_events(events)

    def add_bytes(self, topic: str, data: bytes) -> None:
        """One serialized message of the contract; topics the scores do not use are ignored."""
        if topic == C.TOPIC_WORLD:
            table = decode_table(data)
            if table.fields != C.WORLD_FIELDS:
                raise ValueError(f"world table columns {table.fields}, expected {C.WORLD_FIELDS}")
            self._add_state(np.array(table.data, dtype=np.float64), table.stamp_ns)
        elif topic == C.TOPIC_EVENTS:
            if events_count(data):
                # the message classes (the ROS binding) only when a message must be deserialized
                from evoscen_contract import topics as T
                from rclpy.serialization import deserialize_message

                if self._events_class is None:
                    self._events_class = T.EVENTS.msg_class
                self.add_events(T.parse_events(deserialize_message(data, self._events_class)))
        elif topic == C.TOPIC_MAP_MARKERS and self.lane_segments is None:
            from evoscen_contract import topics as T
            from rclpy.serialization import deserialize_message

            self.lane_segments = lane_segments(deserialize_message(data, T.MAP_MARKERS.msg_class))

    def add_map(self, road) -> None:  # a RoadModel
        """The lane lines of ``road`` (what ``/evoscen/map_markers`` carries)."""
        from evoscen_contract.markers import road_markers

        self.lane_segments = lane_segments(road_markers(road))

    def _add_state(self, table: np.ndarray, t_ns: int) -> None:
        self._last_table, self._last_stamp = table, int(t_ns)
        if self.stream is not None:
            self.stream.add_state(table, t_ns)
        if not self.keep_world:
            self._k += 1
            return
        rows, n_fields = table.shape
        if self._buf is None:
            self._buf = np.empty((n_fields, self._expected, rows), dtype=np.float64)
        elif self._buf.shape[2] != rows or self._buf.shape[0] != n_fields:
            raise ValueError(f"world table of {rows} vehicles at t = {t_ns} ns, "
                             f"the run started with {self._buf.shape[2]}")
        if self._k == self._buf.shape[1]:
            grown = np.empty((n_fields, 2 * self._k, rows), dtype=np.float64)
            grown[:, : self._k] = self._buf
            self._buf = grown
        self._buf[:, self._k, :] = table.T
        self._k += 1
        self._times_ns.append(int(t_ns))

    # ------------------------------------------------------------------ result

    @property
    def states(self) -> int:
        """World states collected so far."""
        return self._k

    def last_nonfinite(self) -> tuple[int, str, float] | None:
        """``(vehicle id, field, value)`` of the first NaN/inf cell of the last state, else None."""
        table = self._last_table
        bad = ~np.isfinite(table)
        if not bad.any():
            return None
        v, j = (int(i[0]) for i in np.nonzero(bad))
        vid = table[v, C.WORLD_FIELDS.index("id")]
        return (int(vid) if np.isfinite(vid) else v), C.WORLD_FIELDS[j], float(table[v, j])

    def stamps_ns(self) -> list[int]:
        """The stamps of the states collected so far (ns; empty without ``keep_world``)."""
        return self._times_ns

    @property
    def last_stamp_ns(self) -> int | None:
        """The stamp of the last state collected (ns)."""
        return self._last_stamp

    def stream_info(self, *, scenario: dict | None = None, external_sut: bool = False) -> dict[str, Any]:
        """The report's ``run`` section of a scored stream (:func:`~evoscen_eval.scoring.metrics.run_info_of`)."""
        st = self.stream
        st.finish()
        dt = float(scenario["dt_s"]) if scenario is not None and "dt_s" in scenario else (st.dt_s or 0.1)
        return run_info_of(scenario, external_sut, st.ids, st.sut, st.states, dt, st.duration_s, self.complete,
                           st.first_lengths)

    def run_data(self, *, scenario: dict | None = None, warnings: Iterable[str] = (),
                 external_sut: bool = False) -> RunData:
        """The collected run; ValueError if no world state was collected (or none was kept)."""
        if not self.keep_world:
            raise ValueError("the accumulator scored the states without keeping them (keep_world=False)")
        if not self._k:
            raise ValueError("no world state (/evoscen/world) in the run")
        k = self._k
        if k < self._buf.shape[1] // 2:  # a run cut short: do not keep the unused half
            self._buf = self._buf[:, :k].copy()
        columns = {f: self._buf[j, :k] for j, f in enumerate(C.WORLD_FIELDS)}
        times = np.asarray(self._times_ns, dtype=np.int64)
        roles = columns["role"][0]
        suts = np.flatnonzero(roles == C.ROLE_SUT)
        if len(suts) != 1:
            raise ValueError(f"the world table has {len(suts)} vehicles with role 1 (SUT), expected exactly 1")
        if scenario is not None and "dt_s" in scenario:
            dt = float(scenario["dt_s"])
        elif len(times) > 1:
            dt = float(times[1] - times[0]) * 1e-9
        else:
            dt = 0.1
        return RunData(time_s=times * 1e-9, columns=columns, ids=columns["id"][0].astype(np.int64),
                       sut_index=int(suts[0]), events=list(self.events), dt_s=dt, scenario=scenario,
                       complete=self.complete, warnings=list(warnings), lane_segments=self.lane_segments,
                       external_sut=external_sut)


def lane_segments(markers: Any) -> np.ndarray:
    """``[M, 2, 2]`` segments of the LINE_LIST markers of a map-marker array."""
    segs = []
    for m in markers.markers:
        pts = np.array([(p.x, p.y) for p in m.points], dtype=np.float64)
        if len(pts) >= 2:
            segs.append(pts[: len(pts) // 2 * 2].reshape(-1, 2, 2))
    return np.concatenate(segs) if segs else np.zeros((0, 2, 2))


# ---------------------------------------------------------------------- reading a bag


_USED_TOPICS = {C.TOPIC_WORLD, C.TOPIC_EVENTS, C.TOPIC_MAP_MARKERS}
_USED_TYPES = {name: C.TOPIC_TYPES[name] for name in (C.TOPIC_WORLD, C.TOPIC_EVENTS, C.TOPIC_MAP_MARKERS)}


def _check_channel(channel: Any, schemas: Mapping[int, Any], path: Path) -> None:
    """InputError if a channel of a topic the scores read is not of the contract's type (CDR)."""
    expected = _USED_TYPES[channel.topic]
    schema = schemas.get(channel.schema_id)
    name = schema.name if schema is not None else None
    if name != expected or channel.message_encoding != "cdr" or (schema is not None and schema.encoding != "ros2msg"):
        got = (f"type {name!r} (schema encoding {schema.encoding!r})" if schema is not None
               else f"no schema (id {channel.schema_id})")
        raise InputError(f"bag {str(path)!r}: topic {channel.topic!r} is recorded with {got}, message encoding "
                         f"{channel.message_encoding!r}; expected {expected!r} (ros2msg) as cdr")


class StampCheck:
    """The world states' stamps checked one at a time (see :func:`check_stamps`); holds one entry
    per distinct spacing, not one per state."""

    def __init__(self, dt_ns: int | None, where: str) -> None:
        self.dt_ns = dt_ns if dt_ns is not None and dt_ns > 0 else None
        self.where = where
        self.states = 0
        self._prev: int | None = None
        self._spacings: dict[int, list[int]] = {}  # spacing -> [first state after it, count, stamp before it]

    def add(self, t_ns: int) -> None:
        """The next state's stamp; InputError if it is not after the previous one (or, with a
        known step, not a whole number of steps after it)."""
        k, t = self.states, int(t_ns)
        self.states += 1
        if self._prev is not None:
            d = t - self._prev
            if d <= 0:
                what = "the same stamp as" if d == 0 else "a stamp before"
                raise InputError(f"{self.where}: world state {k} (t = {t} ns) has {what} state {k - 1} "
                                 f"(t = {self._prev} ns): duplicated or reordered world states; expected strictly "
                                 "increasing stamps, one per step")
            if self.dt_ns is not None and d % self.dt_ns != 0:
                self._irregular(k, t, d, self.dt_ns)
            entry = self._spacings.get(d)
            if entry is None:
                self._spacings[d] = [k, 1, self._prev]
            else:
                entry[1] += 1
        self._prev = t

    def _irregular(self, k: int, t: int, d: int, dt_ns: int) -> None:
        raise InputError(f"{self.where}: world state {k} (t = {t} ns) is {d} ns after state {k - 1}: "
                         f"not a whole number of steps of {dt_ns} ns")

    def finish(self) -> list[str]:
        """The warnings (one line for all gaps); InputError for an irregular spacing when the step
        was not known (then it is the smallest spacing)."""
        if self.states < 2:
            return []
        dt_ns = self.dt_ns if self.dt_ns is not None else min(self._spacings)
        if self.dt_ns is None:
            bad = [(e[0], d, e[2]) for d, e in self._spacings.items() if d % dt_ns != 0]
            if bad:
                k, d, before = min(bad)
                self._irregular(k, before + d, d, dt_ns)
        gaps = {d: e for d, e in self._spacings.items() if d > dt_ns}
        if not gaps:
            return []
        count = sum(e[1] for e in gaps.values())
        missing = sum(e[1] * (d // dt_ns - 1) for d, e in gaps.items())
        first_d = min(gaps, key=lambda d: gaps[d][0])
        return [f"{self.where}: {count} gap{'s' if count > 1 else ''} in the world states, {missing} step"
                f"{'s' if missing != 1 else ''} missing (the first: {first_d // dt_ns - 1} after t = "
                f"{gaps[first_d][2]} ns); scored as recorded: {self.states} states, the states around a gap "
                "taken as consecutive"]


def check_stamps(times_ns: list[int] | np.ndarray, dt_ns: int | None, where: str) -> list[str]:
    """Check the world states' stamps: strictly increasing, one step ``dt_ns`` apart.

    A stamp equal to or before the previous one (a duplicated or reordered state, which the
    scores would count as extra steps) is an InputError; a stamp a whole number of steps
    after the previous one (states missing: a gap) is reported as a warning, one line for
    all gaps, and the run is scored as recorded (the scores then treat the states on either
    side of a gap as consecutive); any other spacing is an InputError (without ``dt_ns`` the
    step is the smallest spacing). Returns the warnings.
    """
    check = StampCheck(dt_ns, where)
    for t in np.asarray(times_ns, dtype=np.int64).tolist():
        check.add(t)
    return check.finish()


def read_run(bag_dir: Path | str) -> RunData:
    """The run recorded in a bag (directory or ``.mcap`` file).

    Reads the file sequentially, so a bag cut short (a killed run) or corrupt part-way still
    gives the states before the damage: :attr:`RunData.warnings` then says what was lost and
    how many states were read. A bag without ``run_end`` is flagged the same way.

    Raises:
        InputError: no such bag, not an MCAP file, nothing readable, or no world state.
    """
    path, acc, scenario, external_sut, warnings = _read_bag(bag_dir, RunAccumulator())
    try:
        return acc.run_data(scenario=scenario, warnings=warnings, external_sut=external_sut)
    except ValueError as exc:
        raise InputError(f"bag {str(path)!r}: {exc}") from None


@dataclass
class ScoredBag:
    """A bag scored as it was read (:func:`score_bag`), without keeping its states."""

    stream: Any
    """The finished :class:`~evoscen_eval.scoring.streaming.ScoreStream`."""
    info: dict[str, Any]
    """The report's ``run`` section."""
    warnings: list[str]
    lane_segments: np.ndarray | None


def score_bag(bag_dir: Path | str, override: Any = None) -> ScoredBag:
    """Score the run in a bag in one pass, in memory independent of its length: as :func:`read_run`
    reads it (same checks, warnings and errors), under ``override`` (an EvaluationConfig) or the
    recorded scenario's evaluation settings."""
    acc = RunAccumulator(keep_world=False)

    def start(scenario: dict | None) -> None:
        ev = override if override is not None else evaluation_settings_of(scenario)
        dt = scenario.get("dt_s") if scenario is not None else None
        acc.start_scoring(ev, float(dt) if isinstance(dt, (int, float)) and not isinstance(dt, bool) else None)

    path, acc, scenario, external_sut, warnings = _read_bag(bag_dir, acc, start)
    try:
        info = acc.stream_info(scenario=scenario, external_sut=external_sut)
    except ValueError as exc:
        raise InputError(f"bag {str(path)!r}: {exc}") from None
    return ScoredBag(acc.stream, info, warnings, acc.lane_segments)


def _read_bag(bag_dir: Path | str, acc: RunAccumulator, before_first_state: Any = None
              ) -> tuple[Path, RunAccumulator, dict | None, bool, list[str]]:
    """Feed ``acc`` the bag's messages in file order (see :func:`read_run`); ``before_first_state(scenario)``
    is called before the first world state is added. Returns (file, acc, scenario, external SUT, warnings)."""
    from evoscen_record.bag_reader import bag_file
    from mcap.records import Channel, Message, Metadata, Schema
    from mcap.stream_reader import StreamReader

    path = bag_file(Path(bag_dir))
    channels: dict[int, str] = {}
    schemas: dict[int, Any] = {}
    scenario: dict | None = None
    external_sut = False
    warnings: list[str] = []
    stamps: StampCheck | None = None
    where = f"bag {str(path)!r}: topic {C.TOPIC_WORLD!r}"
    try:
        stream = open(path, "rb")  # noqa: SIM115
    except OSError as exc:
        raise InputError(f"bag {str(path)!r}: cannot open: {exc.strerror or exc}") from None
    damage: str | None = None
    with stream:
        try:
            for record in StreamReader(stream, validate_crcs=True).records:
                if isinstance(record, Message):
                    topic = channels.get(record.channel_id)
                    if topic in _USED_TOPICS:
                        if topic == C.TOPIC_WORLD and stamps is None:
                            stamps = StampCheck(_dt_ns(scenario), where)
                            if before_first_state is not None:
                                before_first_state(scenario)
                        acc.add_bytes(topic, record.data)
                        if topic == C.TOPIC_WORLD:
                            bad = acc.last_nonfinite()
                            if bad is not None:
                                raise InputError(
                                    f"bag {str(path)!r}: topic {topic!r}, step {acc.states - 1} "
                                    f"(t = {acc.last_stamp_ns} ns): field {bad[1]!r} of vehicle {bad[0]} is "
                                    f"{bad[2]}; expected finite values")
                            stamps.add(acc.last_stamp_ns)
                elif isinstance(record, Channel):
                    if record.topic in _USED_TOPICS:
                        _check_channel(record, schemas, path)
                    channels[record.id] = record.topic
                elif isinstance(record, Metadata) and record.name == SCENARIO_METADATA:
                    scenario = _parse_scenario(record.metadata.get(SCENARIO_KEY), path)
                    steps = (scenario or {}).get("steps")
                    if isinstance(steps, int) and not isinstance(steps, bool):
                        acc.expect(steps + 1)
                    external_sut = _parse_sut_source(record.metadata.get(SUT_SOURCE_KEY), path)
                elif isinstance(record, Schema):
                    schemas[record.id] = record
        except InputError:
            raise
        except (TableDecodeError, ValueError) as exc:
            damage = f"undecodable message ({exc})"
        except Exception as exc:  # noqa: BLE001 - truncated or corrupt data: keep the prefix
            damage = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
    if acc.states == 0:
        why = f" ({damage})" if damage else ""
        raise InputError(f"bag {str(path)!r}: no readable world state (/evoscen/world){why}")
    if damage is not None:
        warnings.append(f"bag {str(path)!r} is truncated or corrupt ({damage}): evaluated the readable "
                        f"prefix, {acc.states} world states ({acc.states - 1} steps)")
    elif not acc.complete:
        warnings.append(f"bag {str(path)!r} has no run_end event (the run did not finish): evaluated "
                        f"{acc.states} world states ({acc.states - 1} steps)")
    if stamps is not None:
        warnings.extend(stamps.finish())
    if scenario is None:
        warnings.append(f"bag {str(path)!r} carries no scenario configuration (metadata record "
                        f"{SCENARIO_METADATA!r}): default evaluation settings used")
    return path, acc, scenario, external_sut, warnings


def _dt_ns(scenario: dict | None) -> int | None:
    """The step of a recorded scenario in ns (None if it has none)."""
    if scenario is not None and isinstance(scenario.get("dt_s"), (int, float)) and scenario["dt_s"] > 0:
        return round(float(scenario["dt_s"]) * 1e9)
    return None


def _parse_sut_source(value: str | None, path: Path) -> bool:
    """True when the metadata record says the SUT was a user's node."""
    if value is None:
        return False
    if value != EXTERNAL_SUT:
        raise InputError(f"bag {str(path)!r}: metadata record {SCENARIO_METADATA!r}: key {SUT_SOURCE_KEY!r} = "
                         f"{value!r}: expected {EXTERNAL_SUT!r} (or no such key)")
    return True


def _parse_scenario(text: str | None, path: Path) -> dict | None:
    if not text:
        return None
    from evoscen_sim.limits import check_yaml_depth

    check_yaml_depth(text, f"bag {str(path)!r}: the scenario metadata record", "the YAML text")
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise InputError(f"bag {str(path)!r}: the scenario metadata record is not YAML: {exc}") from None
    if not isinstance(data, dict):
        raise InputError(f"bag {str(path)!r}: the scenario metadata record is not a mapping")
    return data


def traffic_of(scenario: dict | None, lengths: np.ndarray | None, sut_index: int) -> dict[str, Any]:
    """Which traffic a run had, from its recorded scenario and the first world state's lengths: the
    make-up (a scenario without ``bvs.makeup`` was ``uniform``: docs/bv-profiles.md), the learned BVs'
    policy set (``shipped`` resolved to the make-up's set) and the BVs per class (a truck is longer
    than :data:`~evoscen_sim.traffic.makeup.TRUCK_MIN_LENGTH_M`; the class of a slot is fixed for the run)."""
    from evoscen_sim.traffic.makeup import TRUCK_MIN_LENGTH_M, shipped_policy_set

    bvs = (scenario or {}).get("bvs") or {}
    makeup = bvs.get("makeup") or "uniform"
    policies = None
    if bvs.get("driver") == "learned":
        policies = (((scenario or {}).get("models") or {}).get("learned") or {}).get("policy_dir") or "shipped"
        if policies == "shipped":
            policies = f"shipped ({shipped_policy_set(makeup)})"
    cars = trucks = None
    if lengths is not None:
        others = np.delete(np.asarray(lengths, dtype=float), sut_index)
        trucks = int(np.count_nonzero(others > TRUCK_MIN_LENGTH_M))
        cars = int(others.size - trucks)
    return {"makeup": makeup, "policy_set": policies, "bv_cars": cars, "bv_trucks": trucks}


def run_info_of(scenario: dict | None, external_sut: bool, ids: np.ndarray, sut_index: int, states: int,
                dt_s: float, duration_s: float, complete: bool, lengths: np.ndarray | None = None) -> dict[str, Any]:
    """:func:`run_info` from its parts (a streamed run has no :class:`RunData`); ``lengths``: the
    vehicles' lengths in the first world state (the BVs per class)."""
    sc = scenario or {}
    return {
        "scenario": sc.get("name"),
        "seed": sc.get("seed"),
        "sut_model": EXTERNAL_SUT if external_sut else (sc.get("sut") or {}).get("model"),
        "bv_driver": (sc.get("bvs") or {}).get("driver"),
        **traffic_of(scenario, lengths, sut_index),
        "bv_count": int(ids.shape[0] - 1),
        "sut_id": int(ids[sut_index]),
        "states": states,
        "steps": states - 1,
        "dt_s": dt_s,
        "duration_s": float(duration_s),
        "complete": complete,
    }


RECORDED_BEFORE_KEYS: dict[str, Any] = {
    "rear_conflicts": "none",
    "rear_braking": "any",
    "hard_braking": "own",
    "cut_in_gap_m": 0.0,
    "beside_lane_change": False,
    "undefined_terms": "literal",
    "accel_activity_form": "literal",
    "count_normalisation": "literal",
    "headway_threshold_s": 0.0,
}
"""The value of each evaluation key added after the first bags that reproduces the scores from
before the key existed (docs/evaluation.md §6; ``count_reference_steps`` needs none: it acts
only under ``count_normalisation: method_length``). A bag records its run's whole resolved
``evaluation`` section, so a key missing there means the bag was recorded before the key
existed: it is scored as it was then, not with today's default (``--config`` scores it with
today's definitions)."""


def evaluation_settings_of(scenario: dict | None) -> EvaluationConfig:
    """The evaluation settings of a recorded scenario dict (the defaults without one); a key of
    :data:`RECORDED_BEFORE_KEYS` the recorded section lacks takes its value from before the key existed."""
    recorded = None if scenario is None else scenario.get("evaluation")
    if recorded is None:
        return EvaluationConfig()
    if isinstance(recorded, dict):  # anything else: evaluation_from_dict's one-line error
        recorded = {**RECORDED_BEFORE_KEYS, **recorded}
    return evaluation_from_dict(recorded, "the bag's recorded scenario")
