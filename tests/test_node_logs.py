"""The node graph's log files (evoscen_bringup.node_logs; docs/recording.md, "Node logs"): a node's output
copied to its log file with its ``error:`` lines kept, a log that cannot be written not stopping the node,
and which node's line is the run's one ``error:`` line."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from evoscen_bringup.node_logs import Errors, LauncherLog, NodeLog, the_error_line

NODE_OUTPUT = ("[WARN] [1796535303.750146387] [evoscen_sim]: controller 'evoscen_sut' ended before answering step 3\n"
               "error: sut model 'x': act() at step 3 raised RuntimeError: boom (x.py:9)\n"
               "Traceback (most recent call last):\n")


def _node(path: Path, errors: Errors) -> tuple[subprocess.Popen, NodeLog]:
    """A process writing NODE_OUTPUT to stdout and stderr (half each), its output copied to ``path``."""
    code = (f"import sys; text = {NODE_OUTPUT!r}.splitlines(True); sys.stdout.write(text[0]); sys.stdout.flush(); "
            "sys.stderr.write(''.join(text[1:])); sys.exit(3)")
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    return proc, NodeLog("evoscen_sut", proc.stdout, path, errors)


def test_a_nodes_output_goes_to_its_log_file_with_its_error_lines_kept(tmp_path):
    errors = Errors()
    proc, log = _node(tmp_path / "evoscen_sut.log", errors)
    assert proc.wait(timeout=30) == 3
    log.join(10)
    assert (tmp_path / "evoscen_sut.log").read_text() == NODE_OUTPUT and log.complete
    assert errors.lines() == [("evoscen_sut", "sut model 'x': act() at step 3 raised RuntimeError: boom (x.py:9)")]


def test_a_log_that_cannot_be_written_is_read_all_the_same(tmp_path):
    errors = Errors()
    proc, log = _node(tmp_path / "no such folder" / "evoscen_sut.log", errors)
    assert proc.wait(timeout=30) == 3  # the node is never blocked or failed by its log
    log.join(10)
    assert not log.complete and len(errors.lines()) == 1
    launcher = LauncherLog(tmp_path / "no such folder" / "launcher.log", 0.0)
    launcher("evoscen_sut started")
    assert not launcher.complete


def test_the_error_line_is_the_deciding_nodes():
    ok = {"evoscen_eval": 0, "evoscen_sut": 0, "evoscen_sim": 0}
    said = [("evoscen_sim", "evoscen_sim: controller 'evoscen_sut' missed 5 consecutive deadline(s)"),
            ("evoscen_sut", "sut model 'x': act() at step 3 raised RuntimeError: boom (x.py:9)")]
    # the controller's own fault (3) over the simulation's line; the simulation's when it alone ended 3
    assert the_error_line(3, {**ok, "evoscen_sut": 3, "evoscen_sim": 3}, said[1:]) == said[1][1]
    assert the_error_line(3, {**ok, "evoscen_sut": 3, "evoscen_sim": 0}, said) == said[1][1]
    assert the_error_line(3, {**ok, "evoscen_sim": 3}, said[:1]) == said[0][1]
    # the recorder's host fault (5)
    disk = [("evoscen_eval", "cannot write runs/x/bag/bag_0.mcap: No space left on device (ENOSPC); ...")]
    assert the_error_line(5, {**ok, "evoscen_eval": 5}, disk) == disk[0][1]
    # no node said one: none; a completed or interrupted run repeats no other node's line
    assert the_error_line(3, {**ok, "evoscen_sim": 3}, []) is None
    assert the_error_line(0, ok, said) is None and the_error_line(130, {**ok, "evoscen_sim": 130}, said) is None
