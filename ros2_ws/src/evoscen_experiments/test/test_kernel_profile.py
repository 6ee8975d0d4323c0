"""The kernel profile (evoscen_experiments.kernel_profile): which calls it sees and counts, that it puts every binding
back, that its compute measurement leaves the caller's arrays alone, and the split of a step worked out by hand.
On toy kernels in a module of their own; no figure is asserted (the machines are shared and noisy)."""

from __future__ import annotations

import sys
import types

import numba
import numpy as np
import pytest

from evoscen_experiments.kernel_profile import (KernelProfile, KernelRow, budget_lines, copied, lines, profile_kernels,
                                                split)
from evoscen_sim.errors import InputError


@numba.njit
def _inner(x):
    return x.sum()


@numba.njit
def _outer(x):
    return _inner(x) + 1.0


@numba.njit
def _add_into(out, x):
    for i in range(out.shape[0]):
        out[i] += x[i]
    return out.sum()


@pytest.fixture
def toy():
    """A module ``kptoy_kernels`` binding the three kernels, called through its attributes as the product calls its
    kernels through module globals."""
    mod = types.ModuleType("kptoy_kernels")
    mod.inner, mod.outer, mod.add_into = _inner, _outer, _add_into
    mod.alias = _add_into  # a second binding of the same kernel: one name, both wrapped
    sys.modules[mod.__name__] = mod
    x = np.arange(4.0)
    _outer(x), _add_into(np.zeros(4), x)  # compiled before the profile
    yield mod
    del sys.modules[mod.__name__]


def test_counts_top_level_calls_only_and_puts_every_binding_back(toy) -> None:
    x = np.arange(4.0)
    out = np.zeros(4)
    with KernelProfile(prefixes=("kptoy",), sample_every=2) as prof:
        assert toy.add_into is not _add_into and toy.alias is toy.add_into
        for _ in range(5):
            toy.add_into(out, x)
        for _ in range(3):
            assert toy.outer(x) == 7.0  # its answer unchanged by the wrapper
    assert toy.add_into is _add_into and toy.alias is _add_into and toy.outer is _outer and toy.inner is _inner
    name = f"{__name__}._add_into"
    assert dict(prof.calls) == {name: 5, f"{__name__}._outer": 3}  # _inner runs inside _outer, unseen
    assert len(prof.samples[name]) == 3  # calls 1, 3 and 5 of every second
    for kept, before in zip(prof.samples[name], (0, 2, 4)):  # out before calls 1, 3, 5
        np.testing.assert_array_equal(kept[0], before * x)
    np.testing.assert_array_equal(out, 5 * x)


def test_samples_are_copies_taken_when_called(toy) -> None:
    x = np.arange(4.0)
    out = np.zeros(4)
    with KernelProfile(prefixes=("kptoy",), sample_every=1) as prof:
        toy.add_into(out, x)
        toy.add_into(out, x)
    assert prof.own_s > 0.0  # the copies' time, kept apart from the calls'
    kept = prof.samples[f"{__name__}._add_into"]
    np.testing.assert_array_equal(kept[0][0], np.zeros(4))  # out as it was before the first call
    np.testing.assert_array_equal(kept[1][0], x)  # and before the second
    assert kept[0][0] is not out and kept[0][1] is not x


def test_compute_leaves_the_callers_arrays_alone_and_needs_the_profile_closed(toy) -> None:
    x = np.arange(4.0)
    out = np.zeros(4)
    with KernelProfile(prefixes=("kptoy",), sample_every=1) as prof:
        toy.add_into(out, x)
        with pytest.raises(RuntimeError, match="close the profile first"):
            prof.compute_s()
    before = out.copy()
    compute = prof.compute_s(repeats=3)
    assert set(compute) == {f"{__name__}._add_into"} and compute[f"{__name__}._add_into"] > 0.0
    np.testing.assert_array_equal(out, before)
    np.testing.assert_array_equal(prof.samples[f"{__name__}._add_into"][0][0], np.zeros(4))


def test_bindings_come_back_when_the_profiled_code_raises(toy) -> None:
    with pytest.raises(ZeroDivisionError), KernelProfile(prefixes=("kptoy",)):
        assert toy.add_into is not _add_into
        _ = 1 / 0
    assert toy.add_into is _add_into and toy.alias is _add_into


def test_rows_and_split_by_hand() -> None:
    prof = KernelProfile(prefixes=("kptoy",))
    prof.calls.update({"a": 10, "b": 5})
    prof.call_s.update({"a": 0.001, "b": 0.0005})
    rows = prof.rows(5, compute={"a": 20e-6, "b": 10e-6})
    # a: 10 calls / 5 steps = 2 a step, 1 ms / 5 = 200 us in calls, 2 x 20 us = 40 us of compute; b: 1, 100, 10
    assert [(r.name, r.calls, round(r.call_us, 9), round(r.compute_us, 9)) for r in rows] == [
        ("a", 2.0, 200.0, 40.0), ("b", 1.0, 100.0, 10.0)]
    s = split(0.004, 5, rows)  # wall 800 us a step; calls 300 of which compute 50
    assert {k: round(v, 9) for k, v in s.items()} == {"wall_us": 800.0, "compute_us": 50.0,
                                                       "call_overhead_us": 250.0, "python_us": 500.0}
    text = lines("toy", 0.004, 5, rows)
    assert text[0] == "toy: 800.0 us a step = compute 50.0 (6%) + call overhead 250.0 + Python 500.0"
    assert text[2] == "   2.00  200.00   40.00  a"
    with pytest.raises(ValueError, match="steps must be >= 1"):
        prof.rows(0, compute={})


def test_copied_copies_arrays_in_plain_tuples_only() -> None:
    a = np.ones(2)
    named = KernelRow("k", 1.0, 2.0, 3.0)
    out = copied((a, (a, 1.0), named, 3))
    assert out[0] is not a and out[1][0] is not a and out[1][1] == 1.0 and out[2] is named and out[3] == 3
    np.testing.assert_array_equal(out[0], a)


@pytest.mark.parametrize("cases, steps, worlds, line", [
    ("highd-level0,nosuch", "10", "2", "--cases: unknown case 'nosuch': expected names from highd-level0, "
                                       "uniform-level0, highd-learned, uniform-learned, batched"),
    ("batched,batched", "10", "2", "--cases 'batched,batched': expected distinct comma-separated names"),
    ("batched", "0", "2", "--steps = '0': expected an integer >= 1"),
    ("batched", "10", "x", "--worlds = 'x': expected an integer >= 1"),
])
def test_profile_kernels_options_are_checked_before_any_work(cases, steps, worlds, line) -> None:
    with pytest.raises(InputError) as err:
        profile_kernels(cases, steps, worlds)
    assert str(err.value) == line


def test_budget_lines_by_hand() -> None:
    splits = {"uniform-level0": {"wall_us": 50.0, "compute_us": 12.5},
              "batched": {"wall_us": 200.0, "compute_us": 30.0}}
    # libsumo 20,000 steps/s = 50 us a step; 5x its vehicle-steps/s on 2 processes: 2 x 50 / 5 = 20 us a world-step
    assert budget_lines(splits, 20_000.0) == [
        "libsumo: 20000 steps/s = 50.0 us a step",
        "  uniform-level0: wall 1.00, compute 0.25 of libsumo's step",
        "  batched: wall 4.00, compute 0.60 of libsumo's step",
        "  batched at 5x libsumo's vehicle-steps/s on 2 processes: 20.0 us a world-step; compute alone is 1.50 of it, "
        "the step 10.00"]


def test_a_failed_sumo_reference_is_one_line_and_the_profile_stands(monkeypatch, capsys) -> None:
    from evoscen_experiments import kernel_profile, sumo_baseline

    monkeypatch.setattr(kernel_profile, "_single", lambda case, steps: (0.002, steps, _fixed_profile()))
    monkeypatch.setattr(sumo_baseline, "sumo_available", lambda: (True, "test"))

    def failed(**_):
        raise RuntimeError("SUMO measurement failed (rc=1): netconvert crashed\ntraceback lines")

    monkeypatch.setattr(sumo_baseline, "measure_sumo_steps_per_second", failed)
    assert profile_kernels("uniform-level0", "10", "2") == 0
    out = capsys.readouterr().out.splitlines()
    # 2 ms over 10 steps = 200 us a step; calls 1 ms / 10 = 100 us, of which 10 x 5 us / 10 = 5 us compute
    assert out[0] == "uniform-level0: one world, 10 steps: 200.0 us a step = compute 5.0 (2%) + call overhead 95.0 + Python 100.0"
    assert out[-1] == "libsumo skipped: SUMO measurement failed (rc=1): netconvert crashed"


def _fixed_profile() -> KernelProfile:
    """A closed profile of one kernel: 10 calls, 1 ms in them, its compute 5 us a call."""
    prof = KernelProfile(prefixes=("kptoy",))
    prof.calls.update({"a": 10})
    prof.call_s.update({"a": 0.001})
    prof.compute_s = lambda *_, **__: {"a": 5e-6}  # type: ignore[method-assign]
    return prof
