"""The mcap library's private internals the recorder relies on (:mod:`evoscen_record.mcap_internals`).

The recorder's fast write paths read and update private attributes of ``mcap.writer.Writer``, its
chunk builder, record writer and statistics; with another mcap release they may be gone or mean
something else. These tests fail, naming what changed, when the installed mcap is not the release
the module was written against, when that release is not the one ``requirements-runtime.txt``
pins, or when a fresh writer lacks one of the private members used — instead of the recorder
silently falling back to the library's slower path. A scan of the sources checks that every
private member used is in the checked lists and that no other module of evoscen_record uses one.
"""

from __future__ import annotations

import io
import re
from importlib import metadata
from pathlib import Path

from mcap.writer import CompressionType, Writer

from evoscen_contract.topics import CONTRACT
from evoscen_record import mcap_internals as MI
from evoscen_record.recorder import BagRecorder

REQUIREMENTS = Path(__file__).resolve().parents[4] / "requirements-runtime.txt"


def test_the_installed_mcap_is_the_pinned_release_the_internals_were_written_against():
    pin = re.search(r"^mcap==(\S+)$", REQUIREMENTS.read_text(encoding="utf-8"), re.M)
    assert pin is not None, f"{REQUIREMENTS} pins no mcap release"
    assert pin.group(1) == MI.MCAP_VERSION, (
        f"requirements-runtime.txt pins mcap {pin.group(1)}, evoscen_record.mcap_internals was written against "
        f"{MI.MCAP_VERSION}: check its private attributes against the new release, then update MCAP_VERSION")
    assert metadata.version("mcap") == MI.MCAP_VERSION, (
        f"mcap {metadata.version('mcap')} is installed, evoscen_record.mcap_internals needs {MI.MCAP_VERSION}")


def _writer() -> Writer:
    writer = Writer(io.BytesIO(), chunk_size=1024, compression=CompressionType.ZSTD)
    writer.start(profile="ros2", library="probe")
    return writer


def test_a_fresh_writer_has_every_private_attribute_the_fast_paths_use():
    writer = _writer()
    assert MI.missing_internals(writer) == [], (
        f"mcap {metadata.version('mcap')}: the recorder's fast write paths need {MI.missing_internals(writer)}")
    assert len(MI.WRITER_ATTRIBUTES) == 10


def test_the_checked_lists_cover_every_private_member_the_module_uses():
    """Every name-mangled writer attribute, chunk-builder and record-writer attribute and
    statistics field the module's code touches is one :func:`missing_internals` checks."""
    source = Path(MI.__file__).read_text(encoding="utf-8")
    code = source.split("def missing_internals", 1)[1]  # after the lists themselves
    assert set(re.findall(r"_Writer__\w+", source)) == set(MI.WRITER_ATTRIBUTES)
    cb_used = set(re.findall(r"\bcb\.(\w+)", code)) | set(re.findall(r"_Writer__chunk_builder\.(\w+)", code))
    assert cb_used <= set(MI.CHUNK_BUILDER_ATTRIBUTES), sorted(cb_used - set(MI.CHUNK_BUILDER_ATTRIBUTES))
    rw_used = set(re.findall(r"record_writer\.(\w+)", code))
    assert rw_used <= set(MI.RECORD_WRITER_ATTRIBUTES), sorted(rw_used - set(MI.RECORD_WRITER_ATTRIBUTES))
    st_used = set(re.findall(r"\bst\.(\w+)", code)) | set(re.findall(r"self\._st\.(\w+)", code))
    assert st_used <= set(MI.STATISTICS_FIELDS), sorted(st_used - set(MI.STATISTICS_FIELDS))
    assert re.findall(r"^from (mcap\._\w+)", source, re.M) == ["mcap._chunk_builder"]


def test_no_other_module_of_the_package_uses_the_private_internals():
    package = Path(MI.__file__).parent
    users = [p.name for p in sorted(package.glob("*.py"))
             if p != Path(MI.__file__) and re.search(r"_Writer__|\bmcap\._", p.read_text(encoding="utf-8"))]
    assert users == []


def test_a_changed_private_member_is_named(monkeypatch):
    writer = _writer()
    cb = writer._Writer__chunk_builder
    del cb.num_messages
    del cb.record_writer._buffer
    del writer._Writer__statistics.chunk_count
    monkeypatch.delattr(MI.MessageIndex, "write")
    assert MI.missing_internals(writer) == ["ChunkBuilder.num_messages", "ChunkBuilder.record_writer._buffer",
                                            "Statistics.chunk_count", "MessageIndex.write"]


def test_the_detector_names_what_is_missing():
    class Bare:
        pass

    assert MI.missing_internals(Bare()) == list(MI.WRITER_ATTRIBUTES)


def test_the_recorder_takes_the_fast_paths_with_the_pinned_release(tmp_path):
    bag = BagRecorder(tmp_path / "bag", CONTRACT)
    assert isinstance(bag._chunk, MI.ChunkMessages) and bag._add_message == bag._chunk.add
    bag.close()
    fast_only = BagRecorder(tmp_path / "fast", CONTRACT, chunk_writes=False)
    assert MI.FastMessages.usable(fast_only._writer)
    fast_only.close()
