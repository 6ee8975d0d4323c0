"""What a person sees in ``run.gif`` and ``clip.gif`` (docs/evaluation.md §7.1): its size, the driving
time per frame and the frame rate, the legend whole in a band of its own, a clip's event mid-animation.

Hand-built runs (``make_run``: steps of 0.1 s; ``rear_run``: 40 states, the SUT's left change in
states 5..9 and a rear-conflict exposure from state 7): every number below follows from the
definitions by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest
from evoscen_contract import contract as C
from evoscen_eval.scenes.clips import write_clip_animation
from evoscen_eval.scoring.animation import (
    FRAME_MS,
    FRAME_S,
    HEAD_PX,
    PX_PER_M,
    VIEW_HEIGHT_M,
    FrameSeries,
    legend_band,
    write_animation,
)
from evoscen_eval.scoring.metrics import evaluate
from evoscen_eval.scoring.report import write_report
from evoscen_eval.scoring.run_fixtures import make_run, rear_run
from evoscen_sim.config.scenario_config import EvaluationConfig
from PIL import Image, ImageChops

EV = EvaluationConfig()


def gif_frames(path):
    """``(size, [duration ms of each frame], [each frame as RGB])`` of a GIF."""
    with Image.open(path) as im:
        size, durations, images = im.size, [], []
        for k in range(im.n_frames):
            im.seek(k)
            durations.append(im.info["duration"])
            images.append(im.convert("RGB"))
    return size, durations, images


def test_the_reports_run_gif_is_wide_fast_and_a_second_of_driving_a_frame_at_most(tmp_path):
    """A 30-s run (300 states of 0.1 s): the report's run.gif has one frame per FRAME_S = 1 s of
    driving, ceil(300 x 0.1 / 1) = 30 frames, each shown 100 ms (10 frames a second), 1280 px wide."""
    run = make_run(300, 3)
    run.columns["x"][:] = run.columns["s"] + 3.0 * np.arange(300)[:, None]  # 30 m/s along x
    run.columns["x"][:, 1] = 1000.0 + 3.0 * np.arange(300) + 30.0  # a BV 30 m ahead
    write_report(run, tmp_path, override=EV)
    size, durations, images = gif_frames(tmp_path / "run.gif")
    driving_s = run.states * run.dt_s
    assert size[0] >= 1280
    assert len(durations) == math.ceil(driving_s / FRAME_S) == 30
    assert driving_s / len(durations) <= 1.0
    assert all(d == FRAME_MS <= 100 for d in durations)
    # the view follows the SUT: its orange box (4.8 m x 1.9 m at 8 px/m) in the middle of the road
    # band in every frame, the grey BV 30 m (240 px) to its right
    view_px = int(VIEW_HEIGHT_M * PX_PER_M)
    for frame in images:
        road = np.asarray(frame)[HEAD_PX:HEAD_PX + view_px]
        rows, cols = np.nonzero(np.all(road == (255, 165, 0), axis=-1))  # the SUT's orange
        assert abs((cols.min() + cols.max()) / 2 - size[0] / 2) <= 2 and abs((rows.min() + rows.max()) / 2 - view_px / 2) <= 2
        assert cols.max() - cols.min() == pytest.approx(4.8 * PX_PER_M, abs=3)
        _, grey = np.nonzero(np.all(road == (127, 127, 127), axis=-1))  # the level-0 BV
        assert (grey.min() + grey.max()) / 2 - (cols.min() + cols.max()) / 2 == pytest.approx(30 * PX_PER_M, abs=2)


def test_a_run_as_long_as_the_demo_keeps_a_second_a_frame(tmp_path):
    """3,001 states (the demo's 300 s) fed in blocks of 100 as the scores are: the series keeps one
    state in 2 (1,501 frames, at most KEEP_FRAMES = 1,600) and draws every 5th, one a second:
    301 frames for 300.1 s of driving."""
    states = 3001
    f = {name: j for j, name in enumerate(C.WORLD_FIELDS)}
    tables = np.zeros((states, 3, len(C.WORLD_FIELDS)))
    tables[:, :, f["x"]] = 30.0 * 0.1 * np.arange(states)[:, None] + np.array([0.0, 20.0, -30.0])
    tables[:, :, f["length"]], tables[:, :, f["width"]], tables[:, :, f["speed"]] = 4.8, 1.9, 30.0
    times = 0.1 * np.arange(states)
    series = FrameSeries()
    for a in range(0, states, 100):
        series.add_block(np.arange(a, min(a + 100, states)), times[a:a + 100], tables[a:a + 100], np.arange(3), 0)
    assert series.stride == 2 and len(series.frames) == 1501
    report = {"safety": {"exposure_list": [], "collision_list": []}}
    assert write_animation(series, None, report, tmp_path / "run.gif") == 301
    with Image.open(tmp_path / "run.gif") as im:
        assert im.n_frames == 301 and im.size[0] >= 1280 and im.info["duration"] <= 100
        assert states * 0.1 / im.n_frames <= 1.0


def test_the_legend_is_whole_in_a_band_below_the_road(tmp_path):
    """Every text of the legend lies inside its band at the animation's width and at narrower ones
    (long entries wrap); in the GIF the band sits below the header and the road (HEAD_PX + 30 m at
    8 px/m) and is drawn as it is, nothing over it."""
    for width in (1280, 640, 320):
        legend = legend_band(width)
        for left, top, right, bottom in legend.text_boxes:
            assert 0 <= left and right <= width and 0 <= top and bottom <= legend.image.height, (width, right, bottom)
    run = rear_run()
    rep = evaluate(run, EV)
    from evoscen_eval.scenes.clips import clip_frames

    assert write_animation(clip_frames(run, 100), None, rep, tmp_path / "a.gif") == 4
    size, _, images = gif_frames(tmp_path / "a.gif")
    legend = legend_band(size[0])
    road_bottom = HEAD_PX + int(round(VIEW_HEIGHT_M * PX_PER_M))
    assert size[1] == road_bottom + legend.image.height
    band = legend.image.convert("RGB")
    for frame in images:
        assert ImageChops.difference(frame.crop((0, road_bottom, size[0], size[1])), band).getbbox() is None


def test_a_clips_animation_is_centred_on_its_event(tmp_path):
    """A clip plays in real time, a frame a state (0.1 s shown 100 ms). Event at state 20 of the
    40-state clip: 20 frames (2,000 ms) before its frame, 19 after; the last is held 100 ms longer so
    that the event's frame is shown mid-animation. An event at state 7 (the clip cut short by the
    run's start): the first frame is held (32 - 7) x 100 ms longer."""
    run = rear_run()
    rep = evaluate(run, EV)
    for event, held in ((20, 39), (7, 0)):
        path = tmp_path / f"clip{event}.gif"
        assert write_clip_animation(run, rep, event, path) == 40
        _, durations, _ = gif_frames(path)
        before, after = sum(durations[:event]), sum(durations[event + 1:])
        assert before == after
        assert [n for n, d in enumerate(durations) if d != 100] == [held]
    assert durations[0] == 100 + (32 - 7) * 100


def test_challenges_are_ticks_on_the_run_bar_and_a_section_of_the_report(tmp_path):
    """A 30-s run whose SUT's leader (vehicle 2) starts braking hard at step 150 (docs/challenges.md): the run
    bar (8 px margins, states 0..300 over 1,280 - 16 px) has a blue tick at 8 + 150 / 300 x 1,264 = 640 px in
    its upper half, and the report lists the onset and the run's weight from the end event."""
    run = make_run(300, 3)
    run.columns["x"][:] = run.columns["s"] + 3.0 * np.arange(300)[:, None]
    run.events += [{"name": C.EVENT_CHALLENGE, "step": 150, "time_s": 15.0, "ids": [2, 1], "accel_mps2": -5.0,
                    "duration_s": 2.0, "multiplier": 250.0, "log_weight": -math.log(250.0), "kind": C.KIND_START},
                   {"name": C.EVENT_CHALLENGE, "step": 300, "time_s": 30.0, "log_weight": -4.5, "distance_m": 800.0,
                    "steps": 1, "kind": C.KIND_END}]
    report = write_report(run, tmp_path, override=EV)
    ch = report["challenge"]
    assert ch["count"] == 1 and ch["onsets"][0]["decel_mps2"] == 5.0 and ch["onsets"][0]["vehicle"] == 2
    assert ch["log_weight"] == -4.5 and ch["weight"] == pytest.approx(math.exp(-4.5)) and ch["complete"]
    _, _, images = gif_frames(tmp_path / "run.gif")
    bar = np.asarray(images[0])[56:60]
    _, cols = np.nonzero(np.all(bar == (31, 119, 180), axis=-1))
    assert cols.size and abs((cols.min() + cols.max()) / 2 - 640) <= 2
    assert "## Challenges" in (tmp_path / "report.md").read_text(encoding="utf-8")
