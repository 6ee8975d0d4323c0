"""Critical-event clips: every SUT collision and exposure of a run as a short bag, a picture and
the command that reproduces it (docs/campaigns.md, "Critical events").

For an event at state k (a collision's step, an exposure's worst state) the clip holds the
run's messages stamped from ``t_k - clip_s`` to ``t_k + clip_s`` (clamped to the run), the
latched topics' last message before that (the map and the roster: a player that opens the
clip sees the road and who is who) and the run's scenario record, in a rosbag2 bag of its
own (``scripts/replay.py``, Foxglove, ``ros2 bag play``). Beside it: a bird's-eye PNG of state
k (the report's snapshot, the vehicles involved outlined red), an animation of the clip in real
time with the event mid-animation (``clip.gif``, :func:`write_clip_animation`) and the command that
runs the same configuration to the clip's end in-process — deterministic, so its bag holds the very
same world states.

Involved vehicles (``clips.json`` ``ids``): a collision's pair; an exposure's counterparts, the
vehicles its rules name (:func:`evoscen_eval.scoring.exposure_rules.involved`: the leader, the follower,
the new follower of a cut-in, the vehicle beside), with the rules themselves in ``rules``.

Severity (the gallery's order): every collision before every exposure; exposures by their
severity (the report's ``exposure_list[i].severity``: at the exposure's worst state the largest
ratio over the rules that hold, 1 at a rule's threshold and 2 at twice the danger — TTC, gap or
headway at half the threshold, braking or DRAC at twice it; docs/evaluation.md §2.1); collisions by
their time.
"""

from __future__ import annotations

import json
import shlex
from pathlib import Path
from typing import Any

import numpy as np
from evoscen_contract import contract as C

from evoscen_eval.scoring.animation import ANIMATION_FRAMES, FrameSeries, write_animation
from evoscen_eval.scoring.exposure_rules import involved

CLIP_S = 5.0
"""Seconds of the run kept on either side of an event (SUMO SSM's default ``extratime``, the
attribution window of docs/evaluation.md §3.1)."""


def events_of(report: dict[str, Any]) -> list[dict[str, Any]]:
    """The run's critical events from its report: SUT collisions, then exposures."""
    out = []
    for c in report["safety"]["collision_list"]:
        out.append({"kind": "collision", "state": int(c["state"]), "time_s": float(c["time_s"]), "ids": list(c["ids"]),
                    "severity": None, "min_ttc_s": None})
    for x in report["safety"]["exposure_list"]:
        out.append({"kind": "exposure", "state": int(x["worst_state"]), "time_s": None, "ids": involved(x),
                    "severity": float(x["severity"]), "min_ttc_s": x["min_ttc_s"],
                    "start_state": int(x["start_state"]), "end_state": int(x["end_state"]),
                    "rules": list(x.get("rules", []))})
    return out


def rank_key(event: dict[str, Any]) -> tuple:
    """Sort key of the gallery: collisions first (by time), then exposures by severity (highest first)."""
    if event["kind"] == "collision":
        return (0, event.get("time_s") or 0.0)
    return (1, -event["severity"])


def read_messages(bag_dir: Path) -> list[tuple[str, int, bytes]]:
    """The bag's messages ``(topic, log time, data)`` in log-time order (ties in file order)."""
    from evoscen_record.bag_reader import open_bag_reader

    return [(topic, t_ns, data) for topic, _type, t_ns, data in open_bag_reader(bag_dir, log_time_order=True)]


def cut_clip(messages: list[tuple[str, int, bytes]], metadata: dict, out_dir: Path, t_from_ns: int,
             t_to_ns: int) -> int:
    """Write the messages stamped in ``[t_from_ns, t_to_ns]`` (and the latched topics' last
    message before) as a bag in ``out_dir`` with the MCAP ``metadata`` records; returns the
    number of messages written."""
    from evoscen_contract import topics as T

    from evoscen_record.recorder import BagRecorder

    latched = {spec.name for spec in T.CONTRACT if spec.qos.durability == "transient_local"}
    before: dict[str, tuple[int, bytes]] = {}
    inside: list[tuple[str, int, bytes]] = []
    for topic, t_ns, data in messages:
        if t_ns < t_from_ns:
            if topic in latched:
                before[topic] = (t_ns, data)
        elif t_ns <= t_to_ns:
            inside.append((topic, t_ns, data))
        else:
            break
    # the run's command topics: one per BV node, in the bag's order (docs/architecture.md §5, "BV nodes")
    bv_nodes = list(dict.fromkeys(T.NODE_BV + topic[len(T.TOPIC_COMMANDS_BV):] for topic, _t, _d in messages
                                  if T.is_bv_command_topic(topic)))
    n = 0
    with BagRecorder(out_dir, T.contract_for(bv_nodes), metadata=metadata) as bag:
        for topic, (t_ns, data) in sorted(before.items(), key=lambda item: item[1][0]):
            bag.write(topic, data, log_time_ns=t_ns)
            n += 1
        for topic, t_ns, data in inside:
            bag.write(topic, data, log_time_ns=t_ns)
            n += 1
    return n


def bag_metadata(bag_dir: Path, name: str) -> dict[str, dict[str, str]]:
    """The MCAP metadata record ``name`` of a bag as ``{name: {key: value}}`` (empty if none)."""
    from mcap.reader import make_reader

    from evoscen_record.bag_reader import bag_file

    with open(bag_file(Path(bag_dir)), "rb") as f:
        for record in make_reader(f).iter_metadata():
            if record.name == name:
                return {name: dict(record.metadata)}
    return {}


def clip_frames(clip, keep: int, k_from: int = 0, k_to: int | None = None) -> FrameSeries:
    """The animation frames of states ``k_from..k_to`` of a :class:`~evoscen_eval.scoring.rundata.RunData`
    (a clip's: all of them; every state up to ``keep``), counted from ``k_from``."""
    series = FrameSeries(keep=max(1, keep))
    stop = clip.states if k_to is None else min(clip.states, k_to + 1)
    if stop > k_from:
        tables = np.stack([np.asarray(clip.columns[f][k_from:stop], dtype=np.float64) for f in C.WORLD_FIELDS],
                          axis=-1)
        series.add_block(np.arange(stop - k_from), np.asarray(clip.time_s[k_from:stop], dtype=np.float64), tables,
                         np.asarray(clip.ids), clip.sut_index)
    return series


def write_clip_animation(clip, report: dict[str, Any], centre: int, path: Path, *, frames: int = ANIMATION_FRAMES,
                         title: str | None = None, k_from: int = 0, k_to: int | None = None) -> int:
    """The animation of a clip (or of states ``k_from..k_to`` of a run; ``report``'s states counted
    from ``k_from``) in real time, a frame a state, the frame of state ``centre`` (from ``k_from``)
    shown in the middle of it (:func:`~evoscen_eval.scoring.animation.frame_notes`); returns the frames written."""
    return write_animation(clip_frames(clip, 4 * max(frames, 1), k_from, k_to), clip.lane_segments, report, path,
                           frames=frames, frame_s=float(clip.dt_s), centre_state=centre, title=title)


def window_report(report: dict[str, Any], k_from: int) -> dict[str, Any]:
    """``report``'s exposures and collisions, their states counted from ``k_from``."""
    safety = report["safety"]
    return {"safety": {
        "exposure_list": [{**x, "start_state": x["start_state"] - k_from, "end_state": x["end_state"] - k_from}
                          for x in safety["exposure_list"]],
        "collision_list": [{**c, "state": int(c["state"]) - k_from} for c in safety["collision_list"]]}}


def window_gif(bag_dir: Path, state: int, path: Path, *, clip_s: float = CLIP_S, title: str | None = None) -> int:
    """The animation of a recorded run's states ``state`` ± ``clip_s`` seconds (clamped to the run), in
    real time, centred on ``state``, every exposure and collision of the run marked (the README's
    picture: docs/evaluation.md §7.1); returns the frames written."""
    from evoscen_eval.scoring.report import report_of
    from evoscen_eval.scoring.rundata import read_run

    run = read_run(bag_dir)
    pad = int(round(clip_s / float(run.dt_s)))
    k_from, k_to = max(0, state - pad), min(run.states - 1, state + pad)
    return write_clip_animation(run, window_report(report_of(run), k_from), state - k_from, path, k_from=k_from,
                                k_to=k_to, title=title)


def clip_report(event: dict[str, Any], k_from: int, dt: float) -> dict[str, Any]:
    """The event as the animation reads a report, its states counted from the clip's first."""
    if event["kind"] == "collision":
        return {"safety": {"exposure_list": [], "collision_list": [
            {"state": event["state"] - k_from, "ids": event["ids"]}]}}
    x = {"start_state": event["start_state"] - k_from, "end_state": event["end_state"] - k_from,
         "rules": event.get("rules", [])}
    return {"safety": {"exposure_list": [x], "collision_list": []}}


def mine_run(bag_dir: Path, report: dict[str, Any], run_dir: Path, *, clip_s: float = CLIP_S,
             scenario_file: Path | None = None, run_name: str | None = None,
             animation_frames: int = ANIMATION_FRAMES) -> list[dict[str, Any]]:
    """A clip, a PNG, an animation and a reproduce command for every critical event of a recorded run.

    Writes ``run_dir/clips/<n>-<kind>-<state>/{bag/, scene.png, clip.gif}`` (the GIF of
    ``animation_frames`` frames; 0: none) and ``run_dir/clips.json``; returns one entry per event
    (what :func:`events_of` gives, plus ``clip``, ``png``, ``gif``, ``command``, ``messages``,
    ``from_state``, ``to_state``; paths relative to ``run_dir``).
    """
    from evoscen_record.scenario_record import SCENARIO_METADATA

    from evoscen_eval.scoring.report import _snapshot, exposure_caption
    from evoscen_eval.scoring.rundata import read_run
    from evoscen_eval.scoring.plot_inputs import Scene

    dt = float(report["run"]["dt_s"])
    states = int(report["run"]["states"])
    messages = read_messages(bag_dir)
    metadata = bag_metadata(bag_dir, SCENARIO_METADATA)
    t0 = next((t for topic, t, _ in messages if topic == C.TOPIC_WORLD), 0)
    pad = int(round(clip_s / dt))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = []
    for n, event in enumerate(events_of(report), 1):
        k = min(event["state"], states - 1)
        k_from, k_to = max(0, k - pad), min(states - 1, k + pad)
        name = f"{n:03d}-{event['kind']}-{k}"
        clip_dir = run_dir / "clips" / name
        count = cut_clip(messages, metadata, clip_dir / "bag", t0 + int(round(k_from * dt * 1e9)),
                         t0 + int(round(k_to * dt * 1e9)))
        clip = read_run(clip_dir / "bag")
        row = k - k_from
        png = None
        if 0 <= row < clip.states:
            scene = Scene(state=k, time_s=k * dt, columns={f: clip.columns[f][row] for f in clip.columns},
                          ids=clip.ids, sut_index=clip.sut_index)
            if event["kind"] == "collision":
                title = f"collision at t = {k * dt:.1f} s"
            else:  # the report's words for the exposure (evoscen_eval.scoring.report.exposure_caption)
                title = f"exposure at its most severe state, t = {k * dt:.1f} s: " + exposure_caption(event)
            png = _snapshot(plt, scene, clip.lane_segments, set(event["ids"]), title, clip_dir, "scene.png")
        gif = None
        if animation_frames > 0 and write_clip_animation(clip, clip_report(event, k_from, dt), k - k_from,
                                                         clip_dir / "clip.gif", frames=animation_frames,
                                                         title=f"{event['kind']} {n}"):
            gif = "clip.gif"
        command = None
        if scenario_file is not None:
            command = (f"python scripts/run_scenario.py --mode inprocess --config {shlex.quote(str(scenario_file))} "
                       f"--steps {k_to} --out {shlex.quote(f'runs/repro/{run_name or run_dir.name}-{name}')}")
        out.append({**event, "state": k, "time_s": k * dt, "clip": f"clips/{name}/bag",
                    "png": f"clips/{name}/{png}" if png else None, "gif": f"clips/{name}/{gif}" if gif else None,
                    "command": command, "messages": count,
                    "from_state": k_from, "to_state": k_to})
    (run_dir / "clips.json").write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")
    return out
