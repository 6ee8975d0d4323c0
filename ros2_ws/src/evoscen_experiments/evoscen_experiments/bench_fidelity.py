"""The benchmark of ``scripts/bench_fidelity.py``: the HighD loader and the behaviour extraction on a
HighD-sized recording (docs/performance.md: its figures in the CHANGELOG).

A synthetic recording of HighD's size (by default 1,000 vehicles over 20,000 frames at 25 Hz,
1,000,000 track rows; both driving directions, three lanes each, cars and trucks, half of the
vehicles changing lanes once) is written in HighD's three-file format with evoscen's writer (every
HighD column, the neighbour relations computed by the same code as the bag export), then loaded and
its behaviour samples extracted in a FRESH process (:data:`CHILD`), whose wall time and peak resident
memory are the figures (targets: < 10 s, < 2 GiB). Randomness comes from one seeded numpy Generator.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TARGET_S = 10.0
TARGET_BYTES = 2 * 1024**3
RATE_HZ = 25.0
LANE_WIDTH_M = 3.75


def synthetic_recording(rng, vehicles: int, frames: int, rows: int):
    """A HighD-sized recording from simple kinematics (see the module docstring; ``rows // vehicles``
    rows per vehicle, at most ``frames``: :func:`run` checks)."""
    import numpy as np

    from evoscen_eval.naturalistic.highd_export import build_recording

    upper = 8.5 + LANE_WIDTH_M * np.arange(4)
    lower = upper[-1] + 2.0 + LANE_WIDTH_M * np.arange(4)
    per_vehicle = max(2, rows // vehicles)
    starts = np.sort(rng.integers(1, frames - per_vehicle + 2, size=vehicles))
    road_length = 42.0 * per_vehicle / RATE_HZ + 20.0
    cols = {c: [] for c in ("frame", "track", "t", "x", "y", "length", "width", "vx", "vy", "ax", "dir")}
    k = np.arange(per_vehicle)
    t = k / RATE_HZ
    for i in range(vehicles):
        direction = int(rng.integers(1, 3))
        truck = rng.random() < 0.2
        length = rng.uniform(12.0, 16.0) if truck else rng.uniform(4.0, 5.0)
        width = 2.5 if truck else rng.uniform(1.8, 2.0)
        v0 = rng.uniform(22.0, 25.0) if truck else rng.uniform(25.0, 40.0)
        amp, period, phase = rng.uniform(0.0, 2.0), rng.uniform(10.0, 40.0), rng.uniform(0.0, 2 * np.pi)
        speed = v0 + amp * np.sin(2 * np.pi * t / period + phase)
        accel = amp * 2 * np.pi / period * np.cos(2 * np.pi * t / period + phase)
        travelled = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) / RATE_HZ)])
        marks = upper if direction == 1 else lower
        lane = int(rng.integers(0, 3))
        y = np.full(per_vehicle, marks[lane] + 0.5 * LANE_WIDTH_M)
        vy = np.zeros(per_vehicle)
        if rng.random() < 0.5:  # one lane change, 4 s long, to an adjacent lane
            target = lane + (1 if lane == 0 else -1 if lane == 2 else int(rng.choice([-1, 1])))
            k0 = int(rng.integers(0, max(1, per_vehicle - 100)))
            frac = np.clip((k - k0) / 100.0, 0.0, 1.0)
            y = y + frac * (target - lane) * LANE_WIDTH_M
            vy = np.where((k >= k0) & (k < k0 + 100), (target - lane) * LANE_WIDTH_M / 4.0, 0.0)
        sign = 1.0 if direction == 2 else -1.0
        cols["frame"].append(starts[i] + k)
        cols["track"].append(np.full(per_vehicle, i + 1))
        cols["t"].append((starts[i] + k - 1) / RATE_HZ)
        cols["x"].append(10.0 + travelled if direction == 2 else road_length - 10.0 - travelled)
        cols["y"].append(y)
        cols["length"].append(np.full(per_vehicle, length))
        cols["width"].append(np.full(per_vehicle, width))
        cols["vx"].append(sign * speed)
        cols["vy"].append(vy)
        cols["ax"].append(sign * accel)
        cols["dir"].append(np.full(per_vehicle, direction, dtype=np.int32))
    c = {name: np.concatenate(v) for name, v in cols.items()}
    return build_recording(frame=c["frame"], track=c["track"], time_s=c["t"], x_center=c["x"], y_center=c["y"],
                           length=c["length"], width=c["width"], x_velocity=c["vx"], y_velocity=c["vy"],
                           x_acceleration=c["ax"], direction=c["dir"], upper_markings=upper, lower_markings=lower,
                           road_length_m=road_length, recording_id=1, frame_rate_hz=RATE_HZ, speed_limit_mps=-1.0,
                           source="synthetic")


def peak_rss_bytes() -> int:
    """This process's peak resident memory (VmHWM; ``ru_maxrss`` would include the parent's
    memory at fork time, which Linux carries across exec)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) * 1024
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def measure(directory: Path) -> None:
    """Child mode: load + extract recording 01 of ``directory``; print JSON figures."""
    from evoscen_eval.naturalistic.behaviour import extract_behaviour
    from evoscen_eval.naturalistic.highd import load_recording

    rss0 = peak_rss_bytes()
    t0 = time.perf_counter()
    rec = load_recording(directory, "01")
    t1 = time.perf_counter()
    samples = extract_behaviour(rec)
    t2 = time.perf_counter()
    peak = peak_rss_bytes()
    from evoscen_eval.naturalistic.similarity import compare

    t3 = time.perf_counter()
    compare(samples.dhw_speed, samples.dhw_speed[::2])  # both 2-D KDEs of the experiment's size
    compare(samples.thw_speed, samples.thw_speed[::2])
    t4 = time.perf_counter()
    print(json.dumps({
        "kde_js_s": t4 - t3,
        "rows": rec.num_rows, "tracks": len(rec.tracks_meta["id"]), "frames": int(rec.tracks["frame"].max()),
        "load_s": t1 - t0, "extract_s": t2 - t1, "peak_rss_bytes": peak,
        "rss_before_bytes": rss0, "car_following_samples": len(samples.dhw_speed),
        "lane_changes": samples.num_mandatory + samples.num_voluntary,
    }))


CHILD = """
import sys
from pathlib import Path
from evoscen_experiments.bench_fidelity import measure
measure(Path(sys.argv[1]))
"""
"""The fresh process that loads and extracts the recording of the directory ``sys.argv[1]``."""


def run(vehicles: int, frames: int, rows: int, seed: int, keep: Path | None) -> int:
    """Generate and write the recording (into ``keep``, else a temporary directory), measure it in a fresh
    process and print the figures; the exit status: 0 both targets met, 1 not (or the child failed, or more
    rows per vehicle than frames). A size below 1 is a one-line InputError."""
    import numpy as np

    from evoscen_eval.naturalistic.highd import write_recording
    from evoscen_experiments.bench import child_env
    from evoscen_sim.errors import InputError

    if min(vehicles, frames, rows) < 1:
        raise InputError("--vehicles, --frames and --rows must be >= 1")
    per_vehicle = max(2, rows // vehicles)
    if per_vehicle > frames:
        print(f"error: --rows {rows}: more rows per vehicle ({per_vehicle}) than --frames {frames}", file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory(prefix="evoscen_bench_highd_") as tmp:
        out = keep if keep is not None else Path(tmp)
        t0 = time.perf_counter()
        rec = synthetic_recording(np.random.default_rng(seed), vehicles, frames, rows)
        t1 = time.perf_counter()
        paths = write_recording(out, rec, overwrite=True)
        t2 = time.perf_counter()
        size = sum(p.stat().st_size for p in paths.values())
        print(f"synthetic HighD recording: {rec.num_rows} rows, {len(rec.tracks_meta['id'])} tracks, "
              f"{int(rec.tracks['frame'].max())} frames; generated in {t1 - t0:.1f} s, written in {t2 - t1:.1f} s "
              f"({size / 1e6:.0f} MB)")
        del rec
        proc = subprocess.run([sys.executable, "-c", CHILD, str(out)], capture_output=True, text=True, check=False,
                              env=child_env())
    if proc.returncode != 0:
        print(proc.stderr, file=sys.stderr)
        return 1
    r = json.loads(proc.stdout.strip().splitlines()[-1])
    total = r["load_s"] + r["extract_s"]
    print(f"load {r['load_s']:.2f} s + extract {r['extract_s']:.2f} s = {total:.2f} s (target < {TARGET_S:g} s); "
          f"peak RSS {r['peak_rss_bytes'] / 2**20:.0f} MiB (interpreter and imports {r['rss_before_bytes'] / 2**20:.0f} MiB; "
          f"target < 2048 MiB)")
    print(f"samples: {r['car_following_samples']} car-following rows, {r['lane_changes']} lane changes; "
          f"KDE + JS of the two car-following distributions (all samples vs every second one): {r['kde_js_s']:.2f} s")
    ok = total < TARGET_S and r["peak_rss_bytes"] < TARGET_BYTES
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1
