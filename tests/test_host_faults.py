"""Faults of the host: a full disk, an output directory made read-only or removed (docs/recording.md,
"Faults of the host").

Unit tests simulate the disk at the operating-system boundary (the bag file's raw writes, which
take bytes up to a capacity and then fail with ENOSPC, as a full disk does); end-to-end tests run
``scripts/run_scenario.py`` on a real 512 KiB tmpfs. The expected figures are derived from an
undisturbed run of the same configuration, read with the ``mcap`` library's reader (not the
recorder's): the bag of a run whose disk filled holds exactly the world states of the reference's
chunks that fit, byte for byte the reference's, and the run says so in one line.
"""

from __future__ import annotations

import errno
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

REPO = Path(__file__).resolve().parents[1]
WORLD = "/evoscen/world"
STEPS = 400


def _cfg(steps: int = STEPS):
    from evoscen_sim.config.scenario_config import load_scenario_config

    return load_scenario_config(None, {"steps": steps, "seed": 5, "sut.model": "mobil"})


def _worlds(mcap: Path) -> list[tuple[int, bytes]]:
    """(log time, bytes) of every world message, read with the mcap library's own reader."""
    from mcap.reader import make_reader

    with open(mcap, "rb") as f:
        channels = make_reader(f).get_summary().channels
        f.seek(0)
        return [(m.log_time, bytes(m.data)) for _s, c, m in make_reader(f).iter_messages()
                if c.topic == WORLD] if channels else []


def _chunks(mcap: Path) -> list[tuple[int, int]]:
    """(end offset of the chunk and its message indexes, last log time) of each chunk, in file order."""
    from mcap.reader import make_reader

    with open(mcap, "rb") as f:
        summary = make_reader(f).get_summary()
    idx = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    out = []
    for c in idx:
        out.append((c.chunk_start_offset + c.chunk_length + c.message_index_length, c.message_end_time))
    return out


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The undisturbed run's bag file."""
    from evoscen_bringup.inprocess import run_inprocess

    bag = tmp_path_factory.mktemp("ref") / "bag"
    run_inprocess(_cfg(), bag_dir=bag, bag_writer="inline")
    return bag / "bag_0.mcap"


def _expected(reference: Path, capacity: int) -> tuple[int, list[tuple[int, bytes]]]:
    """The world states of the reference's chunks that end within ``capacity`` bytes."""
    ends = [t for end, t in _chunks(reference) if end <= capacity]
    worlds = _worlds(reference)
    kept = [w for w in worlds if ends and w[0] <= ends[-1]]
    return len(kept), kept


class _FullDisk:
    """A raw file on a disk with ``budget[0]`` bytes left: writes what fits, then ENOSPC."""

    def __init__(self, path: Path, budget: list[int]) -> None:
        self._f = open(path, "wb", buffering=0)  # noqa: SIM115
        self._budget = budget

    def write(self, data) -> int:
        if self._budget[0] <= 0:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        n = self._f.write(memoryview(data)[: self._budget[0]])
        self._budget[0] -= n
        return n

    def fileno(self) -> int:
        return self._f.fileno()

    def close(self) -> None:
        self._f.close()


def _fill_disk(monkeypatch: pytest.MonkeyPatch, bag: Path, capacity: int, *, stays_full: bool) -> None:
    """The run's bag file fills at ``capacity`` bytes; with ``stays_full`` every later file in the
    bag directory too (no room to finish the bag), else the disk has room once the file is cut back."""
    from evoscen_record import bag_file

    budget = [capacity]
    real = bag_file._open_file
    opened = []

    def fake(path: Path):
        if not str(path).startswith(str(bag)):
            return real(path)
        opened.append(path)
        if len(opened) == 1 or stays_full:
            return _FullDisk(path, budget)
        return real(path)

    monkeypatch.setattr(bag_file, "_open_file", fake)


@pytest.mark.parametrize("writer", ["inline", "process"])
@pytest.mark.parametrize("stays_full", [False, True], ids=["room-after", "stays-full"])
def test_full_disk_mid_run(tmp_path: Path, reference: Path, monkeypatch: pytest.MonkeyPatch,
                           writer: str, stays_full: bool) -> None:
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_record.reindex import reindex_bag
    from evoscen_sim.errors import HostFault

    chunks = _chunks(reference)
    assert len(chunks) > 10
    k = len(chunks) // 2
    capacity = (chunks[k - 1][0] + chunks[k][0]) // 2  # in the middle of chunk k
    n, kept = _expected(reference, capacity)
    assert 0 < n < len(_worlds(reference))
    bag = tmp_path / "bag"
    _fill_disk(monkeypatch, bag, capacity, stays_full=stays_full)
    with pytest.raises(HostFault) as info:
        run_inprocess(_cfg(), bag_dir=bag, bag_writer=writer)
    fault = info.value
    assert fault.errno == errno.ENOSPC and fault.path == bag / "bag_0.mcap"
    assert fault.steps == n
    line = fault.line()
    assert "\n" not in line and str(bag / "bag_0.mcap") in line and "No space left on device" in line
    monkeypatch.undo()  # space freed
    if stays_full:
        assert fault.bag_state == "reindex" and f"python scripts/reindex.py {bag}" in line
        assert not (bag / "metadata.yaml").exists()
        assert (bag / "bag_0.mcap").stat().st_size == chunks[k - 1][0]  # cut back to the last complete chunk
        assert [p.name for p in bag.iterdir()] == ["bag_0.mcap"]  # nothing left of the attempt to finish
        reindex_bag(bag, keep_original=False)
    else:
        assert fault.bag_state == "finished" and "is finished" in line and "reindex" not in line
    assert (bag / "metadata.yaml").is_file()
    assert _worlds(bag / "bag_0.mcap") == kept  # every state before the fault, the reference's bytes


def test_fault_when_finishing_the_bag(tmp_path: Path, reference: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The disk fills while the summary is written: the bag is finished from all its chunks."""
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_sim.errors import HostFault

    capacity = _chunks(reference)[-1][0] + 10  # every chunk fits, the summary does not
    _fill_disk(monkeypatch, tmp_path / "bag", capacity, stays_full=False)
    with pytest.raises(HostFault) as info:
        run_inprocess(_cfg(), bag_dir=tmp_path / "bag", bag_writer="inline")
    assert info.value.bag_state == "finished"
    assert _worlds(tmp_path / "bag" / "bag_0.mcap") == _worlds(reference)


def test_unwritable_metadata_yaml(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """metadata.yaml cannot be written (the directory became read-only): one line, the MCAP complete."""
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_sim.errors import HostFault

    real = Path.write_text

    def refuse(self: Path, *a, **kw):
        if self.name == "metadata.yaml":
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(self))
        return real(self, *a, **kw)

    monkeypatch.setattr(Path, "write_text", refuse)
    with pytest.raises(HostFault) as info:
        run_inprocess(_cfg(50), bag_dir=tmp_path / "bag", bag_writer="inline")
    assert info.value.errno == errno.EROFS and info.value.bag_state == "reindex"
    assert "metadata.yaml" in info.value.line() and "reindex.py" in info.value.line()
    assert len(_worlds(tmp_path / "bag" / "bag_0.mcap")) == 51


def test_report_that_cannot_be_written_keeps_the_finished_bag(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from evoscen_bringup import inprocess
    from evoscen_sim.errors import HostFault

    def full(*a, **kw):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(tmp_path / "report" / "report.json"))

    monkeypatch.setattr(inprocess, "_report", full)
    with pytest.raises(HostFault) as info:
        inprocess.run_inprocess(_cfg(30), bag_dir=tmp_path / "bag", report_dir=tmp_path / "report",
                                bag_writer="inline")
    assert info.value.bag_state == "finished" and "report.json" in info.value.line()
    assert len(_worlds(tmp_path / "bag" / "bag_0.mcap")) == 31


# ---------------------------------------------------------------------------- end to end, a real tmpfs


def _can_mount() -> bool:
    return hasattr(os, "geteuid") and os.geteuid() == 0 and shutil.which("mount") is not None


@pytest.fixture
def small_fs(tmp_path: Path):
    """A 512 KiB tmpfs, unmounted afterwards."""
    if not _can_mount():
        pytest.skip("needs root to mount a tmpfs")
    mnt = tmp_path / "small"
    mnt.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=512k", "tmpfs", str(mnt)], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs: {r.stderr.strip()}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


def _cli(out: Path, mode: str, steps: int = STEPS) -> list[str]:
    argv = [sys.executable, str(REPO / "scripts" / "run_scenario.py"), "--mode", "graph" if mode == "graph" else "inprocess",
            "--steps", str(steps), "--seed", "5", "--sut", "mobil", "--out", str(out)]
    return argv if mode == "graph" else [*argv, "--quiet", "--bag-writer", mode]


def _error_line(stderr: str) -> str:
    """The one error line (the graph launcher's and the simulation's informational lines aside)."""
    assert "Traceback" not in stderr, stderr
    errors = [ln for ln in stderr.splitlines() if ln.startswith("error:")]
    assert len(errors) == 1, stderr
    return errors[0]


@pytest.mark.e2e
@pytest.mark.parametrize("mode", ["inline", "process", "graph"])
def test_cli_on_a_full_tmpfs(tmp_path: Path, small_fs: Path, reference: Path, mode: str) -> None:
    out = small_fs / "run"
    proc = subprocess.run(_cli(out, mode), capture_output=True, text=True, timeout=300, check=False)
    assert proc.returncode == 5, proc.stderr
    line = _error_line(proc.stderr)
    if mode != "graph":
        assert len([ln for ln in proc.stderr.splitlines() if ln.strip()]) == 1, proc.stderr
    bag = out / "bag"
    # the same line in both runners (the graph's naming its node logs where they could be written)
    assert line.startswith(f"error: cannot write {bag / 'bag_0.mcap'}: No space left on device (ENOSPC)")
    m = re.search(r"holds the (\d+) world states", line)
    assert m and f"python scripts/reindex.py {bag}" in line
    size = (bag / "bag_0.mcap").stat().st_size
    ends = [end for end, _t in _chunks(reference)]
    assert size in ends  # cut back to a chunk boundary of the undisturbed run
    n, kept = _expected(reference, size)
    assert int(m.group(1)) == n
    copy = tmp_path / "recovered"
    shutil.copytree(bag, copy)
    r = subprocess.run([sys.executable, str(REPO / "scripts" / "reindex.py"), str(copy), "--no-keep-original"],
                       capture_output=True, text=True, timeout=120, check=False)
    assert r.returncode == 0, r.stderr
    assert f"{n} world states" in r.stdout
    assert _worlds(copy / "bag_0.mcap") == kept


class _ReadOnly(_FullDisk):
    """A raw file whose file system turns read-only once ``budget[0]`` bytes are written: the write
    that would cross it fails whole with EROFS, and the file can no longer be truncated either."""

    def write(self, data) -> int:
        if len(data) > self._budget[0]:
            self._budget[0] = 0
            raise OSError(errno.EROFS, os.strerror(errno.EROFS))
        self._budget[0] -= len(data)
        return self._f.write(data)

    def fileno(self) -> int:
        if self._budget[0] <= 0:
            raise OSError(errno.EROFS, os.strerror(errno.EROFS))
        return self._f.fileno()


def _run_read_only_after(monkeypatch: pytest.MonkeyPatch, bag: Path, capacity: int, writer: str):
    """Run the reference configuration into ``bag`` on a file system that turns read-only once
    ``capacity`` bytes are written (:class:`_ReadOnly`); its HostFault, the file system writable again."""
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_record import bag_file
    from evoscen_sim.errors import HostFault

    budget = [capacity]
    real = bag_file._open_file

    def fake(path: Path):
        if not str(path).startswith(str(bag)):
            return real(path)
        if budget[0] <= 0:
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(path))
        return _ReadOnly(path, budget)

    monkeypatch.setattr(bag_file, "_open_file", fake)
    with pytest.raises(HostFault) as info:
        run_inprocess(_cfg(), bag_dir=bag, bag_writer=writer)
    monkeypatch.undo()
    return info.value


@pytest.mark.parametrize("writer", ["inline", "process"])
def test_output_made_read_only_mid_run(tmp_path: Path, reference: Path, monkeypatch: pytest.MonkeyPatch,
                                       writer: str) -> None:
    """Every write fails from some point on (the file system remounted read-only): one line naming
    the cause and the reindexer; the reindexer reads exactly the states written before it."""
    from evoscen_record.reindex import reindex_bag

    chunks = _chunks(reference)
    k = len(chunks) // 3
    capacity = (chunks[k - 1][0] + chunks[k][0]) // 2
    n, kept = _expected(reference, capacity)
    bag = tmp_path / "bag"
    fault = _run_read_only_after(monkeypatch, bag, capacity, writer)
    assert fault.errno == errno.EROFS and fault.bag_state == "reindex" and fault.steps == n
    assert "Read-only file system (EROFS)" in fault.line() and f"reindex.py {bag}" in fault.line()
    reindex_bag(bag, keep_original=False)
    assert _worlds(bag / "bag_0.mcap") == kept


def _chunk_record_ends(mcap: Path) -> list[tuple[int, int]]:
    """(end offset of the chunk record alone, without its message indexes; last log time) of each chunk."""
    from mcap.reader import make_reader

    with open(mcap, "rb") as f:
        idx = sorted(make_reader(f).get_summary().chunk_indexes, key=lambda c: c.chunk_start_offset)
    return [(c.chunk_start_offset + c.chunk_length, c.message_end_time) for c in idx]


@pytest.mark.parametrize("writer", ["inline", "process"])
def test_read_only_between_a_chunk_and_its_indexes(tmp_path: Path, reference: Path,
                                                   monkeypatch: pytest.MonkeyPatch, writer: str) -> None:
    """The file system turns read-only after a chunk record reached the file but before its message
    indexes did, and the file cannot be cut back: the chunk is complete, so the reindexer reads its
    states too, and the line must count them (the states it names are the ones the bag holds)."""
    from evoscen_record.reindex import reindex_bag

    records = _chunk_record_ends(reference)
    k = len(records) // 3
    capacity, last = records[k]  # chunk k whole on disk, its indexes not
    kept = [w for w in _worlds(reference) if w[0] <= last]
    assert 0 < len(kept) < len(_worlds(reference))
    bag = tmp_path / "bag"
    fault = _run_read_only_after(monkeypatch, bag, capacity, writer)
    assert (bag / "bag_0.mcap").stat().st_size == capacity  # not cut back: read-only
    assert fault.errno == errno.EROFS and fault.bag_state == "reindex" and fault.steps == len(kept)
    assert f"holds the {len(kept)} world states" in fault.line()
    assert reindex_bag(bag, keep_original=False).steps == len(kept)
    assert _worlds(bag / "bag_0.mcap") == kept


def test_bag_directory_removed_mid_run(tmp_path: Path) -> None:
    """The bag's directory is removed while the run writes: one line naming metadata.yaml, the bag gone."""
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_sim.errors import HostFault

    bag = tmp_path / "out" / "bag"

    def remove(k: int) -> None:
        if k == 100:
            shutil.rmtree(tmp_path / "out")

    with pytest.raises(HostFault) as info:
        run_inprocess(_cfg(200), bag_dir=bag, bag_writer="inline", progress=remove)
    assert info.value.bag_state == "lost" and info.value.errno == errno.ENOENT
    line = info.value.line()
    assert str(bag / "metadata.yaml") in line and "is gone" in line and "\n" not in line


@pytest.mark.e2e
def test_evaluate_cli_on_a_full_disk(tmp_path: Path, small_fs: Path) -> None:
    """scripts/evaluate.py whose report does not fit: one line naming the file, status 5."""
    from evoscen_bringup.inprocess import run_inprocess

    bag = tmp_path / "bag"
    run_inprocess(_cfg(50), bag_dir=bag, bag_writer="inline")
    st = os.statvfs(small_fs)
    (small_fs / "filler").write_bytes(b"\0" * max(st.f_bavail * st.f_frsize - 4096, 0))
    proc = subprocess.run([sys.executable, str(REPO / "scripts" / "evaluate.py"), str(bag), "--out",
                           str(small_fs / "report")], capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 5, proc.stderr
    line = _error_line(proc.stderr)
    assert line.startswith(f"error: cannot write {small_fs / 'report'}") and "(ENOSPC)" in line, line
    assert "bag" not in line.split(";")[1]  # no bag of this command's own to speak of


@pytest.mark.e2e
def test_cli_report_that_does_not_fit_keeps_the_finished_bag(tmp_path: Path, small_fs: Path) -> None:
    """The bag fits, the report's plots do not: one line naming the report, the bag finished."""
    st = os.statvfs(small_fs)
    (small_fs / "filler").write_bytes(b"\0" * max(st.f_bavail * st.f_frsize - 300 * 1024, 0))  # 300 KiB left
    out = small_fs / "run"
    proc = subprocess.run(_cli(out, "inline", steps=100), capture_output=True, text=True, timeout=300, check=False)
    assert proc.returncode == 5, proc.stderr
    line = _error_line(proc.stderr)
    assert line.startswith(f"error: cannot write {out / 'report'}") and "(ENOSPC)" in line, line
    assert f"the bag {out / 'bag'} is finished, with the 101 world states" in line
    assert (out / "bag" / "metadata.yaml").is_file()
    worlds = _worlds(out / "bag" / "bag_0.mcap")
    assert [t for t, _ in worlds] == [k * 100_000_000 for k in range(101)]


def test_bytes_held_between_flushes_are_bounded_and_change_nothing(tmp_path: Path, reference: Path,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """Past HOLD_BYTES the bag file writes out without waiting for a flush: the same file, byte for byte."""
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_record import bag_file

    writes = []
    real = bag_file.BagFile._write_out

    def counted(self) -> None:
        writes.append(1)
        real(self)

    monkeypatch.setattr(bag_file.BagFile, "HOLD_BYTES", 1000)
    monkeypatch.setattr(bag_file.BagFile, "_write_out", counted)
    run_inprocess(_cfg(), bag_dir=tmp_path / "held" / "bag", bag_writer="inline")
    assert len(writes) > len(_chunks(reference)) + 1  # more write-outs than flushes
    assert (tmp_path / "held" / "bag" / "bag_0.mcap").read_bytes() == reference.read_bytes()


# ---------------------------------------------------------------------------- end to end, a real read-only file system

RO_STEPS = 3000


@pytest.fixture(scope="module")
def reference_ro(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The undisturbed run's bag file, as long as the runs made read-only mid-run."""
    from evoscen_bringup.inprocess import run_inprocess

    bag = tmp_path_factory.mktemp("ref_ro") / "bag"
    run_inprocess(_cfg(RO_STEPS), bag_dir=bag, bag_writer="inline")
    return bag / "bag_0.mcap"


@pytest.fixture
def ext4_fs(tmp_path: Path):
    """A 64 MiB ext4 file system on a loop device (errors=remount-ro), unmounted afterwards; the
    fault campaign's own helpers make it and, later, make it read-only."""
    if not _can_mount() or shutil.which("mkfs.ext4") is None:
        pytest.skip("needs root and mkfs.ext4 to mount an ext4 image")
    from evoscen_experiments.host_faults import mount_ext4

    mnt = tmp_path / "ext4"
    why = mount_ext4(mnt, tmp_path / "ext4.img")
    if why is not None:
        pytest.skip(why)
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


@pytest.mark.e2e
@pytest.mark.parametrize("mode", ["inline", "process", "graph"])
def test_cli_output_made_read_only_mid_run(tmp_path: Path, ext4_fs: Path, reference_ro: Path, mode: str) -> None:
    """The output's file system turns read-only while the bag is written (ext4's emergency read-only,
    as on an I/O error; root cannot write either): status 5, one line naming the bag file and EROFS,
    the bag, which cannot be finished there, rebuilt from a copy by reindex.py holds exactly the
    world states the line names, the undisturbed run's first N byte for byte."""
    from evoscen_experiments.host_faults import make_read_only

    out = ext4_fs / "run"
    bag = out / "bag"
    mcap = bag / "bag_0.mcap"
    proc = subprocess.Popen([*_cli(out, mode, RO_STEPS), "--no-plots"], text=True, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    try:
        end = time.monotonic() + 120
        while proc.poll() is None and time.monotonic() < end and not (mcap.exists() and mcap.stat().st_size > 150_000):
            time.sleep(0.01)
        assert proc.poll() is None, "the run ended before its output was made read-only"
        assert make_read_only(ext4_fs) is None
        t_fault = time.monotonic()
        _out, stderr = proc.communicate(timeout=60)
        after = time.monotonic() - t_fault
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 5, stderr
    assert after < 10.0, f"the run ended {after:.1f} s after the fault"
    line = _error_line(stderr)
    if mode != "graph":
        assert len([ln for ln in stderr.splitlines() if ln.strip()]) == 1, stderr
    # the same line in both runners; the graph's node logs are on the read-only output, so not named as whole
    m = re.fullmatch(
        rf"error: cannot write {re.escape(str(mcap))}: Read-only file system \(EROFS\); the bag "
        rf"{re.escape(str(bag))} holds the (\d+) world states recorded before it, but could not be finished; "
        rf"free space on the disk \(or make the output directory writable\), then run: "
        rf"python scripts/reindex.py {re.escape(str(bag))}", line)
    assert m, line
    n = int(m.group(1))
    assert not (bag / "metadata.yaml").exists()
    copy = tmp_path / "recovered"
    shutil.copytree(bag, copy)
    r = subprocess.run([sys.executable, str(REPO / "scripts" / "reindex.py"), str(copy), "--no-keep-original"],
                       capture_output=True, text=True, timeout=120, check=False)
    assert r.returncode == 0, r.stderr
    assert f"{n} world states" in r.stdout, r.stdout
    worlds = _worlds(copy / "bag_0.mcap")  # the mcap library's reader
    assert n > 0 and [t for t, _ in worlds] == [k * 100_000_000 for k in range(n)]
    assert worlds == _worlds(reference_ro)[:n]
