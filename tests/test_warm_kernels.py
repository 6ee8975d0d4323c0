"""A controller node answers its first world message with a spare driver (controller_node._warm_up), so
that the compiled kernels its driver needs are compiled — or loaded from numba's cache — before the
lockstep's deadlines count. A kernel first needed mid-run is compiled there instead: with a cold cache
(a fresh clone, the first run after `make build`) that took ~1.8 s and a BV node missed its 2-s deadline
(docs/recording.md, "Compiled kernels before the first step").

Checked in a fresh process (the suite's own process has compiled most kernels already): every compile
request of a kernel made while the drivers answer a step after step 0 is listed; there must be none.
The runs are short ones that reach a forced merge of a learned BV after step 100 (seeds found by
running: 7 under `highd`, 8 under `uniform`).

Also the warm step of ``make build`` (scripts/warm_kernels.py, :mod:`evoscen.warm_kernels`): which kernels
it finds and counts, and its one-line error for a bad step count."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

SCRIPT = textwrap.dedent(
    """
    import sys
    import numba.core.dispatcher as nd
    import evoscen_bringup.scenario as scen

    state = {"step": -1, "in_commands": False}
    late = {}
    compile_for_args = nd.Dispatcher._compile_for_args

    def watched(self, *args, **kws):
        if state["in_commands"] and state["step"] >= 1:
            late.setdefault(f"{self.py_func.__module__}.{self.py_func.__name__}", state["step"])
        return compile_for_args(self, *args, **kws)

    nd.Dispatcher._compile_for_args = watched
    commands = scen.Scenario.commands

    def counted(self, *a, **k):
        state["step"] += 1
        state["in_commands"] = True
        try:
            return commands(self, *a, **k)
        finally:
            state["in_commands"] = False

    scen.Scenario.commands = counted
    import evoscen

    seed, steps, sut, makeup = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3], sys.argv[4]
    res = evoscen.run_scenario(None, {"seed": seed, "steps": steps, "sut.model": sut, "bvs.makeup": makeup},
                               evaluate=False)
    assert res.status == 0 and res.steps == steps, (res.status, res.steps)
    for name, step in sorted(late.items(), key=lambda kv: kv[1]):
        print(f"late {step} {name}")
    print("steps answered:", state["step"] + 1)
    """
)


@pytest.mark.parametrize("seed,sut,makeup", [(7, "nilsson", "highd"), (8, "stackelberg", "uniform")])
def test_no_kernel_is_first_compiled_after_step_0(seed, sut, makeup):
    res = subprocess.run([sys.executable, "-c", SCRIPT, str(seed), "300", sut, makeup],
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    late = [line for line in res.stdout.splitlines() if line.startswith("late ")]
    assert late == [], f"kernels first compiled after step 0 (step, kernel): {late}"


def test_kernels_lists_the_dispatchers_defined_in_evoscen_modules_and_counts_their_signatures():
    import types

    import numba
    from evoscen.warm_kernels import KernelCount, count, kernels

    def twice(x):
        return 2 * x

    twice.__module__ = "evoscen_sim.warm_probe"
    mod = types.ModuleType("evoscen_sim.warm_probe")
    mod.twice = numba.njit(twice)
    mod.plain = lambda x: x
    other = types.ModuleType("elsewhere")  # not an evoscen package: not listed
    other.twice = mod.twice
    reexported = types.ModuleType("evoscen_bv.warm_probe")  # imported from another module: listed there only
    reexported.twice = mod.twice
    found = kernels({mod.__name__: mod, other.__name__: other, reexported.__name__: reexported})
    assert list(found) == ["evoscen_sim.warm_probe.twice"]
    assert count(found) == KernelCount((), ("evoscen_sim.warm_probe.twice",), 0)
    assert mod.twice(3) == 6 and mod.twice(1.5) == 3.0  # two argument types: two signatures
    assert count(found) == KernelCount(("evoscen_sim.warm_probe.twice",), (), 2)


def test_warm_kernels_script_says_a_bad_step_count_in_one_line():
    res = subprocess.run([sys.executable, "scripts/warm_kernels.py", "--steps", "0"], capture_output=True, text=True,
                         timeout=120)
    assert res.returncode == 2 and res.stdout == ""
    assert res.stderr.strip().splitlines() == [res.stderr.strip()] and "--steps" in res.stderr
