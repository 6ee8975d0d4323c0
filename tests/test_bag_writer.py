"""The in-process runner's bag written by a forked writer process (``bag_writer="process"``, issue 14).

The process writer must give the inline writer's bag byte for byte (its batches handed over
through shared memory, small batches here so that every hand-over path runs: the run waiting
for a free batch, a batch ending inside a step, the final state after a full batch); its
errors reach the run as they would inline (a bag directory that is not empty: the same
InputError line; a writer that fails: the same exception; a writer that dies: one line naming
the bag, status 4 from the CLI); Ctrl-C leaves a finished bag and status 130.
"""

from __future__ import annotations

import errno
import importlib.util
import os
import signal
import subprocess
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

REPO = Path(__file__).resolve().parents[1]
DT_NS = 100_000_000  # dt_s of the shipped config


def _cfg(steps: int, **over):
    from evoscen_sim.config.scenario_config import load_scenario_config

    return load_scenario_config(None, {"steps": steps, **over})


def _record(tmp_path: Path, name: str, cfg, writer: str) -> bytes:
    from evoscen_bringup.inprocess import run_inprocess

    summary = run_inprocess(cfg, bag_dir=tmp_path / name / "bag", bag_writer=writer)
    data = (tmp_path / name / "bag" / "bag_0.mcap").read_bytes()
    assert summary.message_count > 0
    return data


def test_state_copy_gives_the_columns_bit_for_bit() -> None:
    """What the run copies (World.state_arrays, float64 and int64) rebuilds World.columns exactly."""
    from evoscen_bringup.scenario import build_scenario
    from evoscen_sim.physics.world import STATE_FLOATS, STATE_INTS, state_columns

    sc = build_scenario(_cfg(50))
    for _ in range(30):
        sc.step()
    floats, ints = sc.world.state_arrays()
    assert [a.dtype for a in floats] == [np.float64] * len(STATE_FLOATS)
    assert [a.dtype for a in ints] == [np.int64] * len(STATE_INTS)
    f = np.empty((len(floats), sc.world.n))
    i = np.empty((len(ints), sc.world.n), dtype=np.int64)
    f[:] = floats
    i[:] = ints
    copy = state_columns(sc.world.road, (tuple(f), tuple(i)))
    live = sc.world.columns()
    assert list(copy) == list(live)
    for name in live:
        assert copy[name].dtype == live[name].dtype, name
        assert copy[name].tobytes() == live[name].tobytes(), name


@pytest.mark.parametrize(("slots", "steps_per_slot"), [(2, 3), (1, 1), (4, 128)])
def test_process_writer_gives_the_inline_bytes(tmp_path: Path, monkeypatch, slots: int, steps_per_slot: int) -> None:
    from evoscen_record.bag_writer import ProcessRecorder

    cfg = _cfg(60)
    inline = _record(tmp_path, "inline", cfg, "inline")
    monkeypatch.setattr(ProcessRecorder, "slots", slots)
    monkeypatch.setattr(ProcessRecorder, "steps_per_slot", steps_per_slot)
    assert _record(tmp_path, "process", cfg, "process") == inline


def test_process_writer_learned_bvs_and_no_bvs(tmp_path: Path, monkeypatch) -> None:
    """Other command tables: learned BVs (their own arrays), and a run without BVs (no BV commands)."""
    from evoscen_record.bag_writer import ProcessRecorder

    monkeypatch.setattr(ProcessRecorder, "steps_per_slot", 7)
    for name, cfg in (("learned", _cfg(40, **{"bvs.driver": "learned"})), ("alone", _cfg(40, **{"bvs.count": 0, "spawn.ramp_vehicles": 0}))):
        assert _record(tmp_path, f"{name}-p", cfg, "process") == _record(tmp_path, f"{name}-i", cfg, "inline"), name


def test_bag_dir_not_empty_is_the_inline_error(tmp_path: Path) -> None:
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_sim.errors import InputError

    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "other").write_text("x")
    lines = []
    for writer in ("inline", "process"):
        with pytest.raises(InputError) as exc:
            run_inprocess(_cfg(10), bag_dir=bag, bag_writer=writer)
        lines.append(str(exc.value))
    assert lines[0] == lines[1]
    assert lines[0] == f"bag directory {str(bag)!r}: exists and is not empty; give a new or empty directory"


def test_writer_error_is_raised_in_the_run(tmp_path: Path, monkeypatch) -> None:
    """An error of the writer (here a full disk on the first batch) is raised in the run as itself."""
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_record import bag_writer

    def full_disk(*args, **kwargs) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(bag_writer, "_replay", full_disk)  # the forked writer has the patch too
    monkeypatch.setattr(bag_writer.ProcessRecorder, "steps_per_slot", 5)
    with pytest.raises(OSError) as exc:
        run_inprocess(_cfg(100), bag_dir=tmp_path / "bag", bag_writer="process")
    assert exc.value.errno == errno.ENOSPC


def test_writer_error_wins_over_its_end(tmp_path: Path, monkeypatch) -> None:
    """The writer failed and ended before the run wrote to it again: the run's next send finds
    the pipe broken, and the writer's error (not "ended unexpectedly") is what it raises."""
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_record import bag_writer

    def full_disk(*args, **kwargs) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    send = bag_writer.ProcessRecorder._send

    def send_then_wait(self, message: tuple) -> None:
        send(self, message)
        if message[0] == "batch":
            self._proc.join(timeout=30)  # the writer has failed and ended before "close" goes out
            assert self._proc.exitcode == 0

    monkeypatch.setattr(bag_writer, "_replay", full_disk)
    monkeypatch.setattr(bag_writer.ProcessRecorder, "_send", send_then_wait)
    with pytest.raises(OSError) as exc:
        run_inprocess(_cfg(20), bag_dir=tmp_path / "bag", bag_writer="process")
    assert exc.value.errno == errno.ENOSPC


def _dying_writer(monkeypatch) -> None:
    from evoscen_record import bag_writer

    monkeypatch.setattr(bag_writer, "_replay", lambda *args: os._exit(9))
    monkeypatch.setattr(bag_writer.ProcessRecorder, "steps_per_slot", 5)


def test_dead_writer_is_one_line_naming_the_bag(tmp_path: Path, monkeypatch) -> None:
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_record.bag_writer import BagWriterError

    _dying_writer(monkeypatch)
    bag = tmp_path / "bag"
    with pytest.raises(BagWriterError) as exc:
        run_inprocess(_cfg(100), bag_dir=bag, bag_writer="process")
    assert str(exc.value) == (f"bag {str(bag)!r}: the writer process ended unexpectedly (exit code 9); "
                              "the bag is incomplete")


def test_cli_dead_writer_exits_4_with_one_line(tmp_path: Path, monkeypatch, capsys) -> None:
    _dying_writer(monkeypatch)
    spec = importlib.util.spec_from_file_location("run_scenario_cli", REPO / "scripts" / "run_scenario.py")
    cli = importlib.util.module_from_spec(spec)
    monkeypatch.syspath_prepend(str(REPO / "scripts"))
    spec.loader.exec_module(cli)
    out = tmp_path / "run"
    status = cli.main(["--mode", "inprocess", "--steps", "100", "--quiet", "--no-plots", "--bag-writer", "process",
                       "--out", str(out)])
    err = capsys.readouterr().err
    assert status == 4, err
    assert err == (f"error: bag {str(out / 'bag')!r}: the writer process ended unexpectedly (exit code 9); "
                   "the bag is incomplete\n")


@pytest.mark.parametrize("writer", ["process", "inline"])
def test_ctrl_c_leaves_a_finished_bag(tmp_path: Path, writer: str) -> None:
    """SIGINT to the process group (what a terminal's Ctrl-C sends: the writer gets it too)."""
    from diagnostic_msgs.msg import DiagnosticArray
    from evoscen_contract.topics import parse_events
    from evoscen_record.bag_reader import open_bag_reader
    from mcap.reader import make_reader
    from rclpy.serialization import deserialize_message

    out = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, "scripts/run_scenario.py", "--mode", "inprocess", "--steps", "30000",
                             "--quiet", "--no-plots", "--bag-writer", writer, "--out", str(out)],
                            cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True,
                            # as from a terminal: a suite started in the background inherits SIGINT ignored
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        mcap_file = out / "bag" / "bag_0.mcap"
        deadline = time.monotonic() + 60
        while not (mcap_file.exists() and mcap_file.stat().st_size > 2_000_000) and time.monotonic() < deadline:
            time.sleep(0.1)
        os.killpg(proc.pid, signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, f"exit status {proc.returncode}\n{stdout}\n{stderr}"
    assert stderr == f"interrupted: the bag {out / 'bag'} is finished\n"
    bag: dict[str, list[int]] = defaultdict(list)
    events = []
    for topic, _type, t_ns, data in open_bag_reader(out / "bag"):
        bag[topic].append(t_ns)
        if topic == "/evoscen/events":
            events += [(t_ns, ev) for ev in parse_events(deserialize_message(data, DiagnosticArray))]
    with open(mcap_file, "rb") as f:
        assert make_reader(f).get_summary().statistics.message_count == sum(len(v) for v in bag.values())
    assert events[-1][1]["name"] == "evoscen/run_end" and events[-1][1]["kind"] == "interrupted", events[-1]
    k = events[-1][0] // DT_NS
    assert 0 < k < 30000
    for topic in ("/clock", "/evoscen/world", "/evoscen/sut/odom"):  # one per state t_0 .. t_k
        assert bag[topic] == [j * DT_NS for j in range(k + 1)], topic


def test_killed_run_leaves_the_writer_to_finish_the_bag(tmp_path: Path) -> None:
    """SIGKILL to the run alone: its writer sees the pipe close and finishes the bag with what
    it received (a readable MCAP with its summary, every per-step topic contiguous from t_0)."""
    from evoscen_record.bag_reader import open_bag_reader
    from mcap.reader import make_reader

    out = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, "scripts/run_scenario.py", "--mode", "inprocess", "--steps", "30000",
                             "--quiet", "--no-plots", "--bag-writer", "process", "--out", str(out)],
                            cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    mcap_file, metadata = out / "bag" / "bag_0.mcap", out / "bag" / "metadata.yaml"
    try:
        deadline = time.monotonic() + 60
        while not (mcap_file.exists() and mcap_file.stat().st_size > 2_000_000) and time.monotonic() < deadline:
            time.sleep(0.1)
        proc.kill()  # the run only, not its process group
        proc.communicate(timeout=30)
        deadline = time.monotonic() + 30
        while not metadata.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == -signal.SIGKILL
    assert metadata.exists(), "the writer did not finish the bag after the run was killed"
    time.sleep(0.5)  # metadata.yaml is the writer's last file
    stamps: dict[str, list[int]] = defaultdict(list)
    for topic, _type, t_ns, _data in open_bag_reader(out / "bag"):
        stamps[topic].append(t_ns)
    with open(mcap_file, "rb") as f:
        assert make_reader(f).get_summary().statistics.message_count == sum(len(v) for v in stamps.values())
    k = len(stamps["/evoscen/world"]) - 1
    assert 0 < k < 30000
    for topic in ("/clock", "/evoscen/world", "/evoscen/sut/odom"):
        assert stamps[topic] == [j * DT_NS for j in range(k + 1)], topic


def test_auto_and_unknown_writers(monkeypatch) -> None:
    from evoscen_record import bag_writer

    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0})
    assert bag_writer.resolve_writer("auto") == "inline"
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1})
    assert bag_writer.resolve_writer("auto") == "process"
    assert bag_writer.resolve_writer("inline") == "inline"
    with pytest.raises(ValueError, match="bag_writer 'thread': expected one of auto, inline, process"):
        bag_writer.resolve_writer("thread")


def test_ctrl_c_is_noted_then_raised_at_the_second() -> None:
    """The in-process runner's SIGINT handler: the first is noted, the second raises; the
    earlier handler comes back; a caller's own handler is left alone."""
    from evoscen_bringup.inprocess import _CtrlC

    def own(signum, frame) -> None:
        pass

    # Python's handler, as in a terminal (a suite started in the background has SIGINT ignored)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with _CtrlC() as ctrl_c:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)
            assert ctrl_c.pending
            with pytest.raises(KeyboardInterrupt):
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(1)
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
        signal.signal(signal.SIGINT, own)
        with _CtrlC():
            assert signal.getsignal(signal.SIGINT) is own
    finally:
        signal.signal(signal.SIGINT, previous)
