"""What a node accepts from the wire: the checks on command and world tables (pure: numpy only).

The simulation node applies a command table only if it comes from a registered controller's
publisher (the source check is in :mod:`evoscen_contract.graph`, :class:`~evoscen_contract.graph.SourceTaker`)
and :func:`check_commands` finds it well formed:

* it decodes as a flat float64 table (:func:`evoscen_contract.cdr.decode_table`);
* its columns are exactly :data:`~evoscen_contract.topics.COMMAND_FIELDS` (``id, throttle,
  lane_change``) and its frame is ``map``;
* its stamp is the step's ``t_k`` (an *earlier* stamp is a late answer to a step already
  taken: ``stale``, not a fault when it comes from the controller itself);
* its ``id`` column holds exactly the ids of the controller's vehicles: integer valued, no
  unknown id, no duplicate, none missing (any row order);
* every ``throttle`` is finite and in ``[-1, 1]`` (:data:`THROTTLE_RANGE`), every ``lane_change``
  is one of ``-1, 0, +1``.

Every failed check gives a one-line reason (ids listed up to :data:`MAX_LISTED`), which the
simulation node puts into a ``fault`` event. :func:`check_world` is the controllers' check of a
world table.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .cdr import DecodedTable, TableDecodeError, decode_table

#: Allowed ``throttle`` values (normalized, dimensionless; see ``FIELD_DOCS``).
THROTTLE_RANGE: tuple[float, float] = (-1.0, 1.0)
#: Allowed ``lane_change`` values.
LANE_CHANGES: tuple[float, ...] = (-1.0, 0.0, 1.0)
#: Columns of a command table (= ``topics.COMMAND_FIELDS``; repeated here to stay ROS-free).
COMMAND_COLUMNS: tuple[str, ...] = ("id", "throttle", "lane_change")
#: How many offending ids a reason lists.
MAX_LISTED: int = 5

OK, STALE, BAD = "ok", "stale", "bad"


class Check(NamedTuple):
    """The verdict on one message.

    ``status``: :data:`OK`, :data:`STALE` (well formed up to the stamp, which is earlier than
    the step's) or :data:`BAD`; ``reason``: one line ("" when OK); ``table``: the decoded table
    (None when it did not decode).
    """

    status: str
    reason: str = ""
    table: DecodedTable | None = None


def _listed(values) -> str:
    vals = [int(v) if float(v).is_integer() else float(v) for v in list(values)[:MAX_LISTED]]
    more = len(values) - len(vals)
    return str(vals) + (f" (+{more} more)" if more > 0 else "")


def _cells(values: np.ndarray, ids: np.ndarray, mask: np.ndarray) -> str:
    """``id=value`` pairs of the masked rows (at most MAX_LISTED)."""
    rows = np.flatnonzero(mask)
    text = ", ".join(f"id {ids[r]:g}: {float(values[r])!r}" for r in rows[:MAX_LISTED])
    return text + (f" (+{len(rows) - MAX_LISTED} more)" if len(rows) > MAX_LISTED else "")


def check_commands(data: bytes | memoryview | DecodedTable, step_ns: int, expected_ids,
                   frame_id: str = "map") -> Check:
    """Whether a serialized command table is a well-formed answer to the step at ``step_ns``.

    Args:
        data: the serialized table (or an already decoded one).
        step_ns: ``t_k`` of the step being collected (ns).
        expected_ids: the ids of the controller's vehicles (integer valued).
        frame_id: the frame every evoscen table carries.

    Returns:
        :class:`Check`. Never raises for any input bytes.
    """
    if isinstance(data, DecodedTable):
        table = data
    else:
        try:
            table = decode_table(data)
        except TableDecodeError as exc:
            return Check(BAD, f"not a table ({exc})")
    if table.fields != COMMAND_COLUMNS:
        return Check(BAD, f"columns {list(table.fields)[:8]} are not {list(COMMAND_COLUMNS)}", table)
    if table.frame_id != frame_id:
        return Check(BAD, f"frame_id {table.frame_id[:40]!r} is not {frame_id!r}", table)
    if table.stamp_ns != step_ns:
        if 0 <= table.stamp_ns < step_ns:
            return Check(STALE, f"stamp {table.stamp_ns} ns is earlier than the step's {step_ns} ns", table)
        return Check(BAD, f"stamp {table.stamp_ns} ns is not the step's {step_ns} ns", table)
    arr = table.data
    ids = arr[:, 0]
    expected = np.asarray(expected_ids, dtype=np.float64)
    if ids.shape == expected.shape and np.array_equal(ids, expected):
        return _check_values(table, ids)  # the usual case: the controller's ids, in order
    bad_id = ~np.isfinite(ids) | (ids != np.round(ids))
    if bad_id.any():
        return Check(BAD, f"ids that are not integers: {_listed(ids[bad_id])}", table)
    unknown = ids[~np.isin(ids, expected)]
    if unknown.size:
        return Check(BAD, f"unknown ids {_listed(np.unique(unknown))} (this controller drives "
                          f"{expected.size} vehicles)", table)
    uniq, counts = np.unique(ids, return_counts=True)
    if (counts > 1).any():
        return Check(BAD, f"duplicate rows for ids {_listed(uniq[counts > 1])}", table)
    missing = expected[~np.isin(expected, ids)]
    if missing.size:
        return Check(BAD, f"no row for ids {_listed(missing)}", table)
    return _check_values(table, ids)


def _check_values(table: DecodedTable, ids: np.ndarray) -> Check:
    """The throttle and lane-change checks of :func:`check_commands`."""
    throttle, lane_change = table.data[:, 1], table.data[:, 2]
    nonfinite = ~np.isfinite(throttle)
    if nonfinite.any():
        return Check(BAD, f"non-finite throttle ({_cells(throttle, ids, nonfinite)})", table)
    lo, hi = THROTTLE_RANGE
    out = (throttle < lo) | (throttle > hi)
    if out.any():
        return Check(BAD, f"throttle outside [{lo:g}, {hi:g}] ({_cells(throttle, ids, out)})", table)
    bad_lc = ~np.isin(lane_change, LANE_CHANGES)
    if bad_lc.any():
        return Check(BAD, f"lane_change not -1, 0 or 1 ({_cells(lane_change, ids, bad_lc)})", table)
    return Check(OK, "", table)


def check_world(data: bytes | memoryview, fields: tuple[str, ...], rows: int, dt_ns: int,
                final_ns: int, frame_id: str = "map") -> Check:
    """Whether serialized bytes are a world table a controller can answer.

    Columns ``fields``, ``rows`` rows, frame ``frame_id``, a stamp on the step grid in
    ``[0, final_ns]``, finite cells. Never raises for any input bytes.
    """
    try:
        table = decode_table(data)
    except TableDecodeError as exc:
        return Check(BAD, f"not a table ({exc})")
    if table.fields != tuple(fields):
        return Check(BAD, f"columns {list(table.fields)[:8]} are not the world's", table)
    if table.frame_id != frame_id:
        return Check(BAD, f"frame_id {table.frame_id[:40]!r} is not {frame_id!r}", table)
    if table.data.shape[0] != rows:
        return Check(BAD, f"{table.data.shape[0]} rows, the scenario has {rows} vehicles", table)
    t = table.stamp_ns
    if not 0 <= t <= final_ns or t % dt_ns:
        return Check(BAD, f"stamp {t} ns is not a step time in [0, {final_ns}] ns", table)
    if not np.isfinite(table.data).all():
        return Check(BAD, "non-finite cells", table)
    return Check(OK, "", table)
