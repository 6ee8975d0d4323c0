"""Crash-safe recording: chunks bounded in log time, and reindexing a bag cut short.

Bags are made here with :class:`BagRecorder`: ``/clock`` messages every 0.1 s of log time, so with
the default 1 s chunk span every chunk holds exactly 10 messages (the 11th, 1.0 s after the
chunk's first, opens the next) — message counts below follow from that by hand.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from evoscen_contract import topics as T
from evoscen_contract.messages import WorldMessages
from evoscen_record.bag_reader import open_bag_reader
from evoscen_record.recorder import BagRecorder
from evoscen_record.reindex import reindex_bag
from evoscen_sim.errors import InputError

REPO = Path(__file__).resolve().parents[4]
DT_NS = 100_000_000


def _record(bag_dir: Path, n: int, *, close: bool = True) -> BagRecorder:
    bag = BagRecorder(bag_dir, T.CONTRACT, metadata={"evoscen_test": {"k": "v"}})
    for k in range(n):
        bag.write(T.CLOCK.name, WorldMessages.clock(k * DT_NS), k * DT_NS, canonical=True)
    if close:
        bag.close()
    return bag


def _chunks(mcap: Path) -> list:
    from mcap.reader import make_reader

    with open(mcap, "rb") as f:
        return sorted(make_reader(f).get_summary().chunk_indexes, key=lambda c: c.chunk_start_offset)


def _read_all(bag_dir: Path) -> list[int]:
    return [t for _topic, _type, t, _data in open_bag_reader(bag_dir)]


def test_chunks_span_at_most_one_second_of_log_time(tmp_path):
    _record(tmp_path / "bag", 50)
    chunks = _chunks(tmp_path / "bag" / "bag_0.mcap")
    assert len(chunks) == 5
    for c in chunks:
        assert c.message_end_time - c.message_start_time == 9 * DT_NS


def test_killed_recorder_loses_only_the_open_chunk(tmp_path):
    """A recorder that never closes (SIGKILL): every closed chunk is on disk already."""
    bag = _record(tmp_path / "live", 25, close=False)  # chunks of 0..9, 10..19 closed; 20..24 open
    dead = tmp_path / "dead"
    dead.mkdir()
    shutil.copy(bag.mcap_path, dead / "dead_0.mcap")  # what a SIGKILL leaves: no summary, no metadata.yaml
    with pytest.raises(InputError):
        list(open_bag_reader(dead))
    r = reindex_bag(dead)
    assert (r.messages, r.chunks, r.topic_counts[T.CLOCK.name]) == (20, 2, 20)
    assert r.stopped  # the file ended without its footer
    assert _read_all(dead) == [k * DT_NS for k in range(20)]
    assert (dead / "metadata.yaml").is_file() and (dead / "dead_0.mcap.orig").is_file()


def test_reindex_truncated_file_keeps_complete_chunks(tmp_path):
    _record(tmp_path / "bag", 50)
    mcap = tmp_path / "bag" / "bag_0.mcap"
    fourth = _chunks(mcap)[3]
    data = mcap.read_bytes()[: fourth.chunk_start_offset + 20]  # cut inside the 4th chunk
    cut = tmp_path / "cut"
    cut.mkdir()
    (cut / "cut_0.mcap").write_bytes(data)
    r = reindex_bag(cut / "cut_0.mcap")
    assert r.messages == 30 and r.chunks == 3
    assert _read_all(cut) == [k * DT_NS for k in range(30)]
    # rosbags and mcap open the result
    from rosbags.rosbag2 import Reader

    with Reader(cut) as reader:
        assert reader.message_count == 30
        assert [t for _c, t, _d in reader.messages()] == [k * DT_NS for k in range(30)]
    from mcap.reader import make_reader

    with open(cut / "cut_0.mcap", "rb") as f:
        rd = make_reader(f)
        assert rd.get_summary().statistics.message_count == 30
        assert {m.name for m in rd.iter_metadata()} >= {"evoscen_test", "rosbag2"}


def test_reindex_of_a_complete_bag_is_byte_identical(tmp_path):
    _record(tmp_path / "bag", 50)
    before = {p.name: p.read_bytes() for p in (tmp_path / "bag").iterdir()}
    r = reindex_bag(tmp_path / "bag", keep_original=False)
    assert r.messages == 50 and not r.stopped
    after = {p.name: p.read_bytes() for p in (tmp_path / "bag").iterdir()}
    assert after == before


def _cli(*args: object) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "scripts/reindex.py", *map(str, args)], cwd=REPO, capture_output=True,
                          text=True, timeout=120, check=False)


@pytest.mark.e2e  # runs a CLI as a subprocess
def test_cli_reports_what_it_recovered(tmp_path):
    bag = _record(tmp_path / "live", 25, close=False)
    dead = tmp_path / "dead"
    dead.mkdir()
    shutil.copy(bag.mcap_path, dead / "dead_0.mcap")
    res = _cli(dead)
    assert res.returncode == 0, res.stderr
    assert "recovered 20 messages" in res.stdout and f"{T.CLOCK.name}: 20" in res.stdout, res.stdout
    assert "Traceback" not in res.stderr


@pytest.mark.e2e  # runs a CLI as a subprocess
def test_cli_not_mcap_is_one_error_line(tmp_path):
    bad = tmp_path / "bag"
    bad.mkdir()
    (bad / "bag_0.mcap").write_bytes(b"this is not an MCAP file at all" * 10)
    res = _cli(bad)
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "not an MCAP file" in lines[0], res.stderr
    res = _cli(tmp_path / "nosuch")
    assert res.returncode == 2 and res.stderr.startswith("error: ")
