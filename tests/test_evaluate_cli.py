"""``scripts/evaluate.py``: a bag alone gives the report the run wrote; bad bags are clear errors.

The in-process run of the shared fixture (``recorded_run``) wrote ``report/report.json`` while
it ran; evaluating its bag afterwards must give exactly the same numbers. Damaged bags are
made from copies of that bag.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.e2e


def evaluate(*args: object) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "scripts/evaluate.py", *map(str, args)], cwd=REPO,
                          capture_output=True, text=True, timeout=120, check=False)


def error_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.strip()]


def test_offline_report_equals_the_runs_own(recorded_run, tmp_path):
    live = json.loads((recorded_run.out / "report" / "report.json").read_text())
    res = evaluate(recorded_run.bag_dir, "--out", tmp_path / "off")
    assert res.returncode == 0, res.stderr
    offline = json.loads((tmp_path / "off" / "report.json").read_text())
    assert offline["run"].pop("source") == str(recorded_run.bag_dir)
    assert offline == live
    for key in ("safety", "efficiency", "interaction", "intelligence", "complexity"):
        score = offline[key]["score"]  # I_i is undefined (None) in a run without a SUT lane change
        assert isinstance(score, float) or (key == "interaction" and score is None
                                            and offline[key]["defined"] is False), key
    assert isinstance(offline["intelligence"]["score"], float)
    assert set(offline["intelligence"]["weighted"]) == {"safety", "efficiency", "interaction"}
    for name in ("report.md", "ttc.png", "speed.png", "timeline.png", "traffic.png"):
        assert (tmp_path / "off" / name).stat().st_size > 0
    md = (tmp_path / "off" / "report.md").read_text()
    assert md.index("## D, the comparative score") < md.index("## The method's intelligence I")
    assert "| **I** |" in md and "![timeline](timeline.png)" in md
    assert "## Traffic around the SUT" in md and "![traffic](traffic.png)" in md
    assert md == (recorded_run.out / "report" / "report.md").read_text()  # report.md: live = offline too
    # 201 states: under one 300-state window but at least half of one, so one partial window
    traffic = offline["traffic"]
    assert [(w["start_state"], w["states"], w["partial"]) for w in traffic["windows"]] == [(0, 201, True)]
    assert traffic["min_window_mean_bvs"] == traffic["mean_bvs"] == traffic["per_window_mean_bvs"][0]
    assert f"report: {tmp_path / 'off' / 'report.md'}" in res.stdout


def test_the_bag_scored_in_one_pass_equals_the_bag_read_whole(recorded_run):
    """score_bag (one pass, no [K, V] kept: scripts/evaluate.py) and read_run + report_of (the run
    held as arrays) give the same report, to the last bit."""
    from evoscen_eval.scoring.metrics import report_of_stream
    from evoscen_eval.scoring.report import report_of
    from evoscen_eval.scoring.rundata import read_run, score_bag

    scored = score_bag(recorded_run.bag_dir)
    assert report_of_stream(scored.stream, scored.info, scored.warnings) == report_of(read_run(recorded_run.bag_dir))


def test_default_out_and_no_silent_overwrite(recorded_run, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(recorded_run.bag_dir, run / "bag")
    assert evaluate(run / "bag", "--no-plots").returncode == 0
    assert (run / "report_offline" / "report.json").is_file()
    again = evaluate(run / "bag", "--no-plots")
    assert again.returncode == 2 and error_lines(again.stderr) == [
        f"error: --out {run.resolve() / 'report_offline'}: exists and is not empty; choose another --out or pass --overwrite"]
    assert evaluate(run / "bag", "--no-plots", "--overwrite").returncode == 0


def test_config_override_changes_the_settings(recorded_run, tmp_path):
    cfg = tmp_path / "strict.yaml"
    cfg.write_text("evaluation: {ttc_threshold_s: 30.0, weight_safety: 1.0, weight_efficiency: 0, weight_interaction: 0}\n")
    res = evaluate(recorded_run.bag_dir, "--out", tmp_path / "o", "--config", cfg, "--no-plots")
    assert res.returncode == 0, res.stderr
    rep = json.loads((tmp_path / "o" / "report.json").read_text())
    assert rep["settings"]["ttc_threshold_s"] == 30.0
    assert rep["intelligence"]["score"] == rep["safety"]["score"]


def _copy_bag_with_scenario(src: Path, dst: Path, edit) -> None:  # edit: dict -> None
    """Copy the bag ``src`` (a directory) to ``dst`` with its scenario metadata record edited by
    ``edit(scenario_dict)``; schemas, channels and messages are copied as they are, in file order."""
    import yaml
    from evoscen_record.scenario_record import SCENARIO_KEY, SCENARIO_METADATA
    from mcap.records import Channel, Message, Metadata, Schema
    from mcap.stream_reader import StreamReader
    from mcap.writer import Writer

    dst.mkdir(parents=True)
    with open(src / "bag_0.mcap", "rb") as f, open(dst / "bag_0.mcap", "wb") as g:
        out = Writer(g)
        out.start(profile="ros2")
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        for rec in StreamReader(f).records:
            if isinstance(rec, Metadata):
                data = dict(rec.metadata)
                if rec.name == SCENARIO_METADATA:
                    scenario = yaml.safe_load(data[SCENARIO_KEY])
                    edit(scenario)
                    data[SCENARIO_KEY] = yaml.safe_dump(scenario, sort_keys=False)
                out.add_metadata(rec.name, data)
            elif isinstance(rec, Schema) and rec.id not in schemas:
                schemas[rec.id] = out.register_schema(rec.name, rec.encoding, rec.data)
            elif isinstance(rec, Channel) and rec.id not in channels:
                channels[rec.id] = out.register_channel(rec.topic, rec.message_encoding, schemas[rec.schema_id],
                                                        dict(rec.metadata))
            elif isinstance(rec, Message):
                out.add_message(channels[rec.channel_id], rec.log_time, rec.data, rec.publish_time, rec.sequence)
        out.finish()


def test_a_bag_recorded_before_count_normalisation_scores_the_counts_as_counted(recorded_run, tmp_path):
    """A bag whose recorded evaluation section lacks ``count_normalisation`` (recorded before the key
    existed) is scored as it was then: C and E as counted, not scaled to 3,000 steps (200 steps here:
    scaled, they would enter I_s 15 times over)."""
    import math

    from evoscen_eval.scoring.metrics import safety_score

    live = json.loads((recorded_run.out / "report" / "report.json").read_text())
    s = live["safety"]
    assert (s["count_normalisation"], s["steps"], s["count_factor"]) == ("method_length", 200, 15.0)
    assert (s["collisions_used"], s["exposures_used"]) == (15 * s["collisions"], 15 * s["exposures"])
    assert s["score"] == safety_score(15 * s["collisions"], 15 * s["exposures"], 10)

    def drop(scenario: dict) -> None:
        del scenario["evaluation"]["count_normalisation"], scenario["evaluation"]["count_reference_steps"]

    _copy_bag_with_scenario(recorded_run.bag_dir, tmp_path / "older", drop)
    res = evaluate(tmp_path / "older", "--out", tmp_path / "o", "--no-plots")
    assert res.returncode == 0, res.stderr
    old = json.loads((tmp_path / "o" / "report.json").read_text())
    o = old["safety"]
    assert (o["count_normalisation"], o["count_factor"]) == ("literal", 1.0)
    assert (o["collisions"], o["exposures"], o["collisions_used"], o["exposures_used"]) == \
        (s["collisions"], s["exposures"], s["collisions"], s["exposures"])
    assert o["score"] == 0.7 * (1 - min(s["collisions"], 10) / 10) + 0.3 * math.exp(-s["exposures"])
    # every other number is the run's own
    for key in ("efficiency", "interaction", "complexity"):
        assert old[key] == live[key], key
    # and the copy with the keys kept scores as the run did (the copy itself changes nothing)
    _copy_bag_with_scenario(recorded_run.bag_dir, tmp_path / "same", lambda scenario: None)
    assert evaluate(tmp_path / "same", "--out", tmp_path / "s", "--no-plots").returncode == 0
    assert json.loads((tmp_path / "s" / "report.json").read_text())["safety"] == s


@pytest.fixture(scope="module")
def chunked_run(tmp_path_factory, cli):
    """A 300-step run recorded in small chunks (32 KiB), so a cut file keeps whole chunks."""
    root = tmp_path_factory.mktemp("chunked")
    cfg = root / "small_chunks.yaml"
    cfg.write_text("recording: {chunk_size_bytes: 32768}\n")
    res = cli("--config", cfg, "--steps", 300, "--seed", 4, "--out", root / "run", "--quiet", "--no-plots")
    assert res.returncode == 0, res.stderr
    return root / "run"


def test_truncated_bag_evaluates_the_readable_prefix_with_a_warning(chunked_run, tmp_path):
    bag = tmp_path / "bag"
    shutil.copytree(chunked_run / "bag", bag)
    mcap = bag / "bag_0.mcap"
    data = mcap.read_bytes()
    mcap.write_bytes(data[: len(data) // 2])
    res = evaluate(bag, "--out", tmp_path / "o", "--no-plots")
    assert res.returncode == 0, res.stderr
    assert "Traceback" not in res.stderr
    rep = json.loads((tmp_path / "o" / "report.json").read_text())
    steps = rep["run"]["steps"]
    assert 0 < steps < 300 and rep["run"]["complete"] is False
    warnings = [line for line in error_lines(res.stderr) if line.startswith("warning:")]
    assert len(warnings) == 1 and "truncated or corrupt" in warnings[0]
    assert f"{steps + 1} world states ({steps} steps)" in warnings[0]
    assert rep["warnings"] == [warnings[0].removeprefix("warning: ")]


def test_corrupt_chunk_evaluates_the_prefix(chunked_run, tmp_path):
    bag = tmp_path / "bag"
    shutil.copytree(chunked_run / "bag", bag)
    mcap = bag / "bag_0.mcap"
    data = bytearray(mcap.read_bytes())
    at = len(data) * 2 // 3
    data[at:at + 64] = bytes(64)  # zero out bytes in the middle of a compressed chunk
    mcap.write_bytes(bytes(data))
    res = evaluate(bag, "--out", tmp_path / "o", "--no-plots")
    assert res.returncode == 0, res.stderr  # the damage is detected (CRC / decompression): the prefix counts
    rep = json.loads((tmp_path / "o" / "report.json").read_text())
    assert 0 < rep["run"]["steps"] < 300
    assert any("truncated or corrupt" in w for w in rep["warnings"])


def test_bad_bags_are_one_line_errors(tmp_path):
    missing = evaluate(tmp_path / "nope")
    assert missing.returncode == 2
    assert error_lines(missing.stderr) == [f"error: bag {str(tmp_path / 'nope')!r}: no such bag directory or .mcap file"]
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"this is not an mcap file at all" * 10)
    res = evaluate(junk, "--out", tmp_path / "o")
    assert res.returncode == 2 and "Traceback" not in res.stderr
    lines = error_lines(res.stderr)
    assert len(lines) == 1 and lines[0].startswith(f"error: bag {str(junk)!r}: no readable world state")
    empty = tmp_path / "empty"
    empty.mkdir()
    res = evaluate(empty)
    assert res.returncode == 2 and len(error_lines(res.stderr)) == 1 and "expected exactly one" in res.stderr


def test_bad_config_is_one_line_error(recorded_run, tmp_path):
    cfg = tmp_path / "bad.yaml"
    cfg.write_text("evaluation: {window_steps: 0}\n")
    res = evaluate(recorded_run.bag_dir, "--out", tmp_path / "o", "--config", cfg)
    assert res.returncode == 2
    lines = error_lines(res.stderr)
    assert len(lines) == 1 and "'evaluation.window_steps' = 0" in lines[0] and "integer >= 1" in lines[0]
    assert not (tmp_path / "o").exists()


def test_exposures_go_out_as_recorded_events_matching_the_report(cli, tmp_path):
    """A strict TTC threshold makes exposures frequent: each is an evoscen/exposure start event in the bag."""
    from mcap_ros2.reader import read_ros2_messages

    cfg = tmp_path / "strict.yaml"
    cfg.write_text("evaluation: {ttc_threshold_s: 40.0}\n")
    res = cli("--config", cfg, "--steps", 400, "--seed", 2, "--sut", "mobil", "--out", tmp_path / "run", "--quiet",
              "--no-plots")
    assert res.returncode == 0, res.stderr
    report = json.loads((tmp_path / "run" / "report" / "report.json").read_text())
    starts, ends = [], []
    for m in read_ros2_messages(str(tmp_path / "run" / "bag" / "bag_0.mcap"), topics=["/evoscen/events"]):
        for status in m.ros_msg.status:
            if status.name == "evoscen/exposure":
                values = {kv.key: kv.value for kv in status.values}
                (starts if values["kind"] == "start" else ends).append(int(values["step"]))
    exposures = report["safety"]["exposure_list"]
    assert len(exposures) > 0
    assert starts == [e["start_state"] for e in exposures]
    assert ends == [e["end_state"] for e in exposures if not e["open_at_end"]]
