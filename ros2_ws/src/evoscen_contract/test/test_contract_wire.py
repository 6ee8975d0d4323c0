"""The wire checks (evoscen_contract.wire) and the table decoder under hostile bytes.

Hand-built command tables, one defect each; the verdicts and reasons are worked out by hand.
The fuzz test mutates valid tables with a seeded generator: the decoder may only raise
TableDecodeError, whatever the bytes.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from evoscen_contract.cdr import TableDecodeError, TableEncoder, decode_table
from evoscen_contract.topics import COMMAND_FIELDS, WORLD_FIELDS
from evoscen_contract.wire import BAD, OK, STALE, check_commands, check_world

STEP_NS = 700_000_000  # t_7 at dt 0.1 s
BV_IDS = [1, 2, 3, 4]


def table(rows, stamp_ns=STEP_NS, fields=COMMAND_FIELDS, frame="map") -> bytes:
    return TableEncoder(fields, frame).encode(np.asarray(rows, dtype=np.float64).reshape(-1, len(fields)), stamp_ns)


GOOD = [[1, 0.5, 0], [2, -1.0, 1], [3, 1.0, -1], [4, 0.0, 0]]


def test_well_formed_table_is_ok_in_any_row_order():
    assert check_commands(table(GOOD), STEP_NS, BV_IDS).status == OK
    assert check_commands(table(GOOD[::-1]), STEP_NS, BV_IDS).status == OK


@pytest.mark.parametrize("rows, reason", [
    ([[0, 0.5, 0], *GOOD[1:]], "unknown ids [0]"),  # the SUT's id on the BV topic
    ([[-1, 0.5, 0], *GOOD[1:]], "unknown ids [-1]"),
    ([[20, 0.5, 0], *GOOD[1:]], "unknown ids [20]"),
    ([[1.5, 0.5, 0], *GOOD[1:]], "ids that are not integers: [1.5]"),
    ([[math.nan, 0.5, 0], *GOOD[1:]], "ids that are not integers"),
    ([*GOOD, GOOD[0]], "duplicate rows for ids [1]"),
    (GOOD * 3, "duplicate rows for ids [1, 2, 3, 4]"),
    (GOOD[:3], "no row for ids [4]"),
    ([], "no row for ids [1, 2, 3, 4]"),
    ([GOOD[0], [2, math.nan, 0], *GOOD[2:]], "non-finite throttle (id 2: nan)"),
    ([GOOD[0], [2, math.inf, 0], *GOOD[2:]], "non-finite throttle (id 2: inf)"),
    ([GOOD[0], [2, -math.inf, 0], *GOOD[2:]], "non-finite throttle (id 2: -inf)"),
    ([GOOD[0], [2, 1.0000001, 0], *GOOD[2:]], "throttle outside [-1, 1] (id 2: 1.0000001)"),
    ([GOOD[0], [2, -3.0, 0], *GOOD[2:]], "throttle outside [-1, 1] (id 2: -3.0)"),
    ([GOOD[0], [2, 0.0, 2], *GOOD[2:]], "lane_change not -1, 0 or 1 (id 2: 2.0)"),
    ([GOOD[0], [2, 0.0, math.nan], *GOOD[2:]], "lane_change not -1, 0 or 1 (id 2: nan)"),
])
def test_malformed_rows_are_bad(rows, reason):
    check = check_commands(table(rows), STEP_NS, BV_IDS)
    assert check.status == BAD
    assert reason in check.reason, check.reason
    assert "\n" not in check.reason


def test_wrong_fields_frame_and_stamp():
    wrong = check_commands(table(GOOD, fields=("id", "throttle", "steer")), STEP_NS, BV_IDS)
    assert wrong.status == BAD and "columns ['id', 'throttle', 'steer'] are not" in wrong.reason
    swapped = check_commands(table([[r[0], r[2], r[1]] for r in GOOD], fields=("id", "lane_change", "throttle")),
                             STEP_NS, BV_IDS)
    assert swapped.status == BAD
    frame = check_commands(table(GOOD, frame="odom"), STEP_NS, BV_IDS)
    assert frame.status == BAD and "frame_id 'odom'" in frame.reason
    future = check_commands(table(GOOD, stamp_ns=STEP_NS + 100_000_000), STEP_NS, BV_IDS)
    assert future.status == BAD and "stamp 800000000 ns is not the step's 700000000 ns" in future.reason
    negative = check_commands(table(GOOD, stamp_ns=-100_000_000), STEP_NS, BV_IDS)
    assert negative.status == BAD and "stamp -100000000 ns" in negative.reason
    late = check_commands(table(GOOD, stamp_ns=STEP_NS - 100_000_000), STEP_NS, BV_IDS)
    assert late.status == STALE


@pytest.mark.parametrize("data", [b"", b"\x00\x01\x00\x00", bytes(64), bytes(range(64)), b"\xff" * 100])
def test_garbage_is_bad_not_an_exception(data):
    check = check_commands(data, STEP_NS, BV_IDS)
    assert check.status == BAD and check.reason.startswith("not a table")


def test_check_world():
    n, dt, final = 3, 100_000_000, 10 * 100_000_000
    rows = np.arange(n * len(WORLD_FIELDS), dtype=float).reshape(n, -1)
    enc = TableEncoder(WORLD_FIELDS, "map")
    assert check_world(enc.encode(rows, dt), WORLD_FIELDS, n, dt, final).status == OK
    assert "rows" in check_world(enc.encode(rows[:2], dt), WORLD_FIELDS, n, dt, final).reason
    assert "stamp" in check_world(enc.encode(rows, -dt), WORLD_FIELDS, n, dt, final).reason
    assert "stamp" in check_world(enc.encode(rows, dt + 1), WORLD_FIELDS, n, dt, final).reason
    assert "stamp" in check_world(enc.encode(rows, final + dt), WORLD_FIELDS, n, dt, final).reason
    bad = rows.copy()
    bad[1, 3] = math.nan
    assert "non-finite" in check_world(enc.encode(bad, dt), WORLD_FIELDS, n, dt, final).reason
    assert check_world(b"\x00" * 64, WORLD_FIELDS, n, dt, final).status == BAD


def test_decode_table_hand_made_defects():
    good = bytearray(table(GOOD))
    frame_at = 16  # payload: stamp (8) then the frame_id string: length (4) at byte 12, text at 16
    bad_utf8 = bytearray(good)
    bad_utf8[frame_at] = 0xFF
    for data in (bytes(bad_utf8), bytes(good[:40]), bytes(good[:-9]), bytes(64)):
        with pytest.raises(TableDecodeError):
            decode_table(data)


def test_decode_table_fuzz_raises_only_table_decode_error():
    """20,000 mutated tables (seeded): decoded or TableDecodeError, never another exception."""
    rng = np.random.default_rng(16)
    seeds = [table(GOOD), table([[0, 0.1, 0]]), TableEncoder(WORLD_FIELDS, "map").encode(np.zeros((21, 17)), 0),
             TableEncoder(("é", "x"), "märkte").encode(np.ones((2, 2)), 5)]
    decoded = errors = 0
    for i in range(20_000):
        data = bytearray(seeds[i % len(seeds)])
        kind = rng.integers(5)
        if kind == 0:  # flip random bytes
            for at in rng.integers(0, len(data), size=rng.integers(1, 8)):
                data[at] = int(rng.integers(256))
        elif kind == 1:  # cut short
            data = data[:int(rng.integers(0, len(data)))]
        elif kind == 2:  # random bytes
            data = bytearray(rng.integers(0, 256, size=int(rng.integers(0, 200)), dtype=np.uint8).tobytes())
        elif kind == 3:  # a random 32-bit value at a random 4-aligned place (sizes, lengths, counts)
            at = 4 * int(rng.integers(0, max(1, len(data) // 4)))
            data[at:at + 4] = int(rng.integers(0, 2**32)).to_bytes(4, "little")
        else:  # non-UTF-8 into the text
            data[16 + int(rng.integers(0, 3))] = int(rng.integers(0x80, 0x100))
        try:
            decode_table(bytes(data))
            decoded += 1
        except TableDecodeError:
            errors += 1
    assert decoded + errors == 20_000
    assert errors > 5_000 and decoded > 100  # both paths exercised
