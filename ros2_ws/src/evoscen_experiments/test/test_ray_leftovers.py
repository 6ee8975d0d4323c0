"""The note of a campaign driver's Ray session and the ending of what a killed driver left
(:mod:`evoscen_experiments.ray_leftovers`), on this process and on a pid that does not exist."""

from __future__ import annotations

import json
import os

from evoscen_experiments.ray_leftovers import DRIVER_FILE, end_leftovers, start_time, zombie

NO_SUCH_PID = 2**22 + 1  # above Linux's largest pid (pid_max at most 2^22)


def test_start_time_and_zombie_of_this_process_and_of_none():
    assert start_time(os.getpid()).isdigit()
    assert not zombie(os.getpid())
    assert start_time(NO_SUCH_PID) is None and zombie(NO_SUCH_PID)


def test_no_note_nothing_to_end(tmp_path):
    assert end_leftovers(tmp_path) == []


def test_a_driver_that_still_runs_keeps_its_session(tmp_path):
    note = tmp_path / DRIVER_FILE
    note.write_text(json.dumps({"pid": os.getpid(), "start": start_time(os.getpid()),
                                "session_dir": "/tmp/ray/session_none"}), encoding="utf-8")
    assert end_leftovers(tmp_path) == [] and note.exists()


def test_a_dead_drivers_note_is_removed(tmp_path):
    """The driver is gone and its session has no process left: nothing to end, the note goes."""
    note = tmp_path / DRIVER_FILE
    note.write_text(json.dumps({"pid": NO_SUCH_PID, "start": "1", "session_dir": str(tmp_path / "session_gone")}),
                    encoding="utf-8")
    assert end_leftovers(tmp_path, grace_s=0.0) == [] and not note.exists()
