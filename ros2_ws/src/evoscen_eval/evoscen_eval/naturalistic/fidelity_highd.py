"""The traffic's fidelity against highD's shipped aggregates (docs/fidelity.md).

highD (Krajewski, Bock, Kloeker, Eckstein: "The highD Dataset", IEEE ITSC 2018) sees each vehicle
over the ~420 m its drones film. Its per-vehicle summaries — mean speed, minimum time headway
(THW), minimum distance headway (DHW), minimum time to collision (TTC), lane changes — are
shipped here only as aggregates (``data/highd_aggregates.json``, :func:`load_reference`). To be
compared with them, the simulation's background vehicles (BVs) are measured the same way:

1. Each run goes through the HighD export at its own rate
   (:func:`evoscen_eval.naturalistic.highd_export.run_to_highd`, ``frame_rate_hz=None``): a *trip* (HighD track)
   is a vehicle between two entries into the traffic (the ``evoscen/reentry`` events: the window
   re-uses a vehicle's id for its next trip), the window's shifts undone; every row carries HighD's
   ``dhw``, ``thw``, ``ttc`` and ``precedingId`` (leader = the nearest vehicle ahead in the same
   laneId, of any role) and ``laneId``.
2. **[choice] Pieces.** Each BV trip is cut into consecutive pieces of ``piece_m`` (420 m) of
   distance driven, counted from the trip's start (:func:`recording_pieces`). The last, shorter
   part of a trip (the remainder) is a piece only if it is at least ``min_piece_m`` long (default:
   ``piece_m``, so never). Reason: a minimum over a shorter stretch is larger (fewer chances to come
   close), so pieces shorter than highD's would bias the minima up; dropping remainders keeps
   every piece as long as highD's section. A vehicle that leaves the window ends its trip there;
   the id's next trip starts afresh (its own pieces from its own start).
3. Per piece: mean speed (the time mean over its states, as highD's ``meanXVelocity``); minimum
   THW over the states with a leader and THW > 0 (pieces without one have none, as highD's
   ``minTHW``: "vehicles that had a leader"); minimum DHW likewise; minimum TTC over the states
   that were closing on a leader (TTC > 0), only pieces with one (highD: "only vehicles with a
   positive TTC to a leader at some time"). The rules are the export's own ``minTHW``/``minDHW``/
   ``minTTC`` rules, applied per piece.
4. **Classes**: a vehicle longer than ``truck_length_m`` (7 m; highD's trucks: p5 7.07 m, cars:
   p95 6.16 m) is a truck, by the ``length`` column of the piece's first state (a slot may carry
   another vehicle on its next trip).
5. **Lane changes per vehicle-km**: every change of a BV trip's laneId (highD's
   ``numLaneChanges``) over the distance its trips drove (highD: the sum of ``traveledDistance``),
   over whole trips, remainders included (a rate needs no pieces). **[choice] Density** of a run
   (for the by-density rates): the time mean of the vehicles (any role) on the mainline lanes
   (lane >= 1) inside the section ``[s_sut - behind_m, s_sut + ahead_m]`` (the traffic window,
   the scenario's ``traffic.behind_m``/``ahead_m``), per km and per mainline lane — like highD's
   recording-direction mean over its filmed section. A run's trips fall into its density's bin.
6. **Similarity** (docs/method.md §5.3, (26)-(27)): S = 1 - JS(highD || simulation), log base 2,
   over the reference histogram's own bins (:func:`histogram_similarity`). **[choice]** Values
   outside the bins are left out on both sides, as the reference's histograms leave them out
   (their ``n`` exceeds the sum of their counts); the shares left out are reported beside S.

Everything here is ROS-free; :func:`bag_measures` reads bags (:func:`evoscen_eval.scoring.rundata.read_run`),
:func:`run_measures` takes a run in memory (an in-process run's ``RunSummary.run``).
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from evoscen_eval.naturalistic.highd import HighDRecording
from evoscen_eval.naturalistic.highd_export import ExportOptions, VirtualRoad, _reduce_per_track, run_to_highd
from evoscen_eval.naturalistic.similarity import js_divergence

#: The shipped aggregates (package data, docs/fidelity.md).
REFERENCE_PATH = Path(__file__).resolve().parent / "data" / "highd_aggregates.json"
HIGHD_CITATION = ("R. Krajewski, J. Bock, L. Kloeker, L. Eckstein, \"The highD Dataset: A Drone Dataset of "
                  "Naturalistic Vehicle Trajectories on German Highways for Validation of Highly Automated "
                  "Driving Systems\", IEEE ITSC 2018")
CLASSES: tuple[str, ...] = ("all", "car", "truck")


@dataclass(frozen=True)
class PieceConfig:
    """How the simulation's trips are measured (module docstring, docs/fidelity.md)."""

    piece_m: float = 420.0
    """Length of a piece (m): the stretch highD sees each vehicle over."""
    min_piece_m: float | None = None
    """A trip's remainder of at least this length (m) is a piece too; None (default) = ``piece_m``: never."""
    truck_length_m: float = 7.0
    """A vehicle longer than this (m) is a truck."""
    include_sut: bool = False
    """Also measure the SUT's trips (default: BVs only)."""
    behind_m: float | None = None
    """The density section behind the SUT (m); None: the run's ``traffic.behind_m`` (else 150)."""
    ahead_m: float | None = None
    """... ahead of it (m); None: the run's ``traffic.ahead_m`` (else 250)."""

    def __post_init__(self) -> None:
        if not self.piece_m > 0:
            raise ValueError(f"piece_m {self.piece_m!r}: expected a length > 0 (m)")
        if self.min_piece_m is not None and not 0 < self.min_piece_m <= self.piece_m:
            raise ValueError(f"min_piece_m {self.min_piece_m!r}: expected a length in (0, piece_m = {self.piece_m:g}] (m)")
        if not self.truck_length_m > 0:
            raise ValueError(f"truck_length_m {self.truck_length_m!r}: expected a length > 0 (m)")


@dataclass
class Measures:
    """Per-piece and per-trip measures of one or more runs (pooled with :meth:`concat`).

    Piece arrays (one entry per piece): ``truck``, ``mean_speed_mps``, ``min_thw_s``,
    ``min_dhw_m``, ``min_ttc_s`` (NaN where a piece has none), ``run`` (index into ``runs``).
    Trip arrays (one entry per trip, remainders included): ``trip_truck``, ``trip_km``,
    ``trip_lane_changes``, ``trip_run``. ``runs``: one dict per run (source, density, states).
    """

    truck: np.ndarray
    mean_speed_mps: np.ndarray
    min_thw_s: np.ndarray
    min_dhw_m: np.ndarray
    min_ttc_s: np.ndarray
    run: np.ndarray
    trip_truck: np.ndarray
    trip_km: np.ndarray
    trip_lane_changes: np.ndarray
    trip_run: np.ndarray
    runs: list[dict[str, Any]] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    @property
    def pieces(self) -> int:
        return int(self.truck.shape[0])

    def piece_density(self) -> np.ndarray:
        """The density (veh/km/lane) of each piece's run."""
        dens = np.array([r.get("density_veh_per_km_per_lane", np.nan) for r in self.runs], dtype=float)
        return dens[self.run] if self.runs else np.full(self.pieces, np.nan)

    def trip_density(self) -> np.ndarray:
        dens = np.array([r.get("density_veh_per_km_per_lane", np.nan) for r in self.runs], dtype=float)
        return dens[self.trip_run] if self.runs else np.full(self.trip_run.shape, np.nan)

    @staticmethod
    def concat(parts: Iterable[Measures]) -> Measures:
        parts = list(parts)
        if not parts:
            return _empty()
        out = _empty()
        offset = 0
        arrays: dict[str, list[np.ndarray]] = {k: [] for k in _ARRAYS}
        for p in parts:
            for k in _ARRAYS:
                a = getattr(p, k)
                arrays[k].append(a + offset if k in ("run", "trip_run") else a)
            out.runs.extend(p.runs)
            out.warnings.extend(p.warnings)
            offset += len(p.runs)
        for k in _ARRAYS:
            setattr(out, k, np.concatenate(arrays[k]))
        return out


_ARRAYS = ("truck", "mean_speed_mps", "min_thw_s", "min_dhw_m", "min_ttc_s", "run",
           "trip_truck", "trip_km", "trip_lane_changes", "trip_run")


def _empty() -> Measures:
    f, b, i = np.zeros(0), np.zeros(0, dtype=bool), np.zeros(0, dtype=np.int64)
    return Measures(b, f, f, f, f, i, b, f, np.zeros(0, dtype=np.int64), i)


# ====================================================================== measuring


def recording_pieces(rec: HighDRecording, config: PieceConfig = PieceConfig(), run_index: int = 0) -> Measures:
    """The pieces and trips of a HighD recording's tracks (module docstring, steps 2-5).

    Tracks of the simulation's SUT (tracksMeta ``evoscenRole`` 1) are left out unless
    ``config.include_sut``; a recording without that column (a real highD one) keeps every track.
    Rows must be sorted by track, then frame (as :class:`HighDRecording` holds them).
    """
    t = rec.tracks
    n = rec.num_rows
    if n == 0:
        return _empty()
    track = t["id"].astype(np.int64)
    keep_ids = rec.tracks_meta["id"].astype(np.int64)
    if "evoscenRole" in rec.tracks_meta and not config.include_sut:
        keep_ids = keep_ids[rec.tracks_meta["evoscenRole"] == 0]
    keep = np.isin(track, keep_ids)
    track = track[keep]
    if track.size == 0:
        return _empty()
    x = rec.x_center()[keep]
    forward = np.where(rec.driving_direction()[keep] == 1, -1.0, 1.0)
    u_abs = forward * x  # distance along the direction of travel
    speed = np.abs(t["xVelocity"][keep])
    length = t["width"][keep]  # HighD's "width" column is the vehicle's length
    lane_id = t["laneId"][keep]
    has_p = t["precedingId"][keep] != 0
    dhw, thw, ttc = t["dhw"][keep], t["thw"][keep], t["ttc"][keep]

    t_start = np.flatnonzero(np.diff(track, prepend=track[0] - 1) != 0)
    t_end = np.append(t_start[1:], track.size) - 1
    rows_per_track = t_end - t_start + 1
    u = u_abs - np.repeat(u_abs[t_start], rows_per_track)  # distance from the trip's start
    u_last = np.repeat(u[t_end], rows_per_track)
    piece_no = np.floor(np.maximum(u, 0.0) / config.piece_m).astype(np.int64)

    # ---- trips: distance and laneId changes (highD's traveledDistance and numLaneChanges)
    same = np.diff(track, prepend=track[0] - 1) == 0
    changes = np.add.reduceat((same & (np.diff(lane_id, prepend=lane_id[0]) != 0)).astype(np.int64), t_start)
    trip_km = (u[t_end]) / 1000.0
    trip_truck = length[t_start] > config.truck_length_m

    # ---- pieces: rows of one track with one piece number
    p_start = np.flatnonzero((np.diff(track, prepend=track[0] - 1) != 0) | (np.diff(piece_no, prepend=-1) != 0))
    p_rows = np.diff(np.append(p_start, track.size))
    k = piece_no[p_start]
    reach = u_last[p_start] - k * config.piece_m  # how far the trip went beyond the piece's start
    full = reach >= config.piece_m
    min_piece = config.piece_m if config.min_piece_m is None else config.min_piece_m
    remainder_ok = reach >= min_piece - 1e-9
    valid = full | remainder_ok

    def per_piece(values: np.ndarray, ok: np.ndarray, how: str) -> np.ndarray:
        red = _reduce_per_track(values, ok, p_start, how)
        return np.where(red < 0, np.nan, red)

    with np.errstate(invalid="ignore"):
        mean_speed = np.add.reduceat(speed, p_start) / p_rows
        min_thw = per_piece(thw, has_p & (thw > 0) & np.isfinite(thw), "min")
        min_dhw = per_piece(dhw, has_p & (dhw > 0), "min")
        min_ttc = per_piece(ttc, has_p & (ttc > 0) & np.isfinite(ttc), "min")
    return Measures(
        truck=(length[p_start] > config.truck_length_m)[valid], mean_speed_mps=mean_speed[valid],
        min_thw_s=min_thw[valid], min_dhw_m=min_dhw[valid], min_ttc_s=min_ttc[valid],
        run=np.full(int(valid.sum()), run_index, dtype=np.int64),
        trip_truck=trip_truck, trip_km=trip_km, trip_lane_changes=changes.astype(np.int64),
        trip_run=np.full(t_start.size, run_index, dtype=np.int64),
        runs=[{"source": rec.source}], warnings=list(rec.warnings))


def run_density(run: Any, config: PieceConfig = PieceConfig()) -> float:
    """The run's density (vehicles per km per mainline lane, module docstring step 5)."""
    cols = run.columns
    scen = getattr(run, "scenario", None) or {}
    traffic = scen.get("traffic", {}) if isinstance(scen, dict) else {}
    behind = config.behind_m if config.behind_m is not None else float(traffic.get("behind_m", 150.0))
    ahead = config.ahead_m if config.ahead_m is not None else float(traffic.get("ahead_m", 250.0))
    s = np.asarray(cols["s"], dtype=float)
    lane = np.asarray(cols["lane"], dtype=float)
    lanes = traffic.get("lane_density_per_km")
    n_lanes = len(lanes) if isinstance(lanes, (list, tuple)) and lanes else int(max(1.0, float(np.max(lane))))
    s_sut = s[:, int(run.sut_index)][:, None]
    inside = (lane >= 1) & (s >= s_sut - behind) & (s <= s_sut + ahead)
    return float(np.mean(inside.sum(axis=1))) / ((behind + ahead) / 1000.0) / n_lanes


def run_measures(run: Any, config: PieceConfig = PieceConfig(), road: VirtualRoad | None = None,
                 source: str = "run") -> Measures:
    """The measures of one run (a :class:`~evoscen_eval.scoring.rundata.RunData`), exported at its own rate on
    ``road`` (default: the run's map, :func:`evoscen_eval.naturalistic.fidelity.road_for_run`)."""
    from evoscen_eval.naturalistic.fidelity import road_for_run

    warnings: list[str] = []
    if road is None:
        road, warnings = road_for_run(run)
    rec = run_to_highd(run, replace(ExportOptions(frame_rate_hz=None), road=road))
    m = recording_pieces(rec, config)
    m.runs = [{"source": source, "states": int(run.states), "dt_s": float(run.dt_s),
               "density_veh_per_km_per_lane": run_density(run, config)}]
    m.warnings = [*(getattr(run, "warnings", None) or []), *warnings]
    return m


def bag_measures(bags: Iterable[Path | str], config: PieceConfig = PieceConfig()) -> Measures:
    """The pooled measures of bags (InputError for a bag that cannot be read)."""
    from evoscen_eval.scoring.rundata import read_run

    return Measures.concat(run_measures(read_run(b), config, source=str(b)) for b in bags)


# ====================================================================== the reference and the comparison


def load_reference(path: Path | str | None = None) -> dict[str, Any]:
    """The highD aggregates (default: the shipped package data); InputError if unreadable."""
    from evoscen_sim.errors import InputError

    p = Path(path) if path is not None else REFERENCE_PATH
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{p}: cannot read the highD aggregates: {exc}") from None
    if not isinstance(data, dict) or "speed_limit_120_kmh" not in data:
        raise InputError(f"{p}: key 'speed_limit_120_kmh': missing (expected evoscen's highD aggregates)")
    return data


def histogram_similarity(ref_counts: Any, edges: Any, values: Any) -> dict[str, Any]:
    """S = 1 - JS(reference || values) over the reference's bins, log base 2 (module docstring, step 6).

    ``values`` outside ``[edges[0], edges[-1]]`` (and NaN) are left out (the last bin includes its
    right edge, as ``numpy.histogram``); ``similarity`` and ``js`` are NaN when either side has no
    count inside the bins.
    """
    edges = np.asarray(edges, dtype=float)
    ref = np.asarray(ref_counts, dtype=float)
    if ref.shape != (edges.size - 1,):
        raise ValueError(f"histogram_similarity: {ref.size} counts for {edges.size} edges")
    v = np.asarray(values, dtype=float)
    v = v[~np.isnan(v)]
    counts = np.histogram(v, bins=edges)[0]
    below, above = int(np.sum(v < edges[0])), int(np.sum(v > edges[-1]))
    if counts.sum() == 0 or ref.sum() == 0:
        js = float("nan")
    else:
        js = js_divergence(ref, counts)
    return {"similarity": 1.0 - js, "js": js, "edges": edges.tolist(), "highd_counts": ref.tolist(),
            "sim_counts": counts.tolist(), "n": int(v.size), "n_in_bins": int(counts.sum()),
            "n_below": below, "n_above": above}


@dataclass(frozen=True)
class Quantity:
    key: str
    """The reference's key (``speed_limit_120_kmh``) and the Measures attribute."""
    attribute: str
    title: str
    unit: str
    mean: bool = True
    """False: no mean is reported (a TTC at a near-zero closing speed is arbitrarily large)."""


QUANTITIES: tuple[Quantity, ...] = (
    Quantity("per_vehicle_mean_speed_mps", "mean_speed_mps", "mean speed", "m/s"),
    Quantity("per_vehicle_min_thw_s", "min_thw_s", "min THW", "s"),
    Quantity("per_vehicle_min_dhw_m", "min_dhw_m", "min DHW", "m"),
    Quantity("per_vehicle_min_ttc_s", "min_ttc_s", "min TTC", "s", mean=False),
)


def _stats(v: np.ndarray) -> tuple[int, float, float, float]:
    v = v[np.isfinite(v)]
    if v.size == 0:
        return 0, float("nan"), float("nan"), float("nan")
    return int(v.size), float(np.mean(v)), float(np.median(v)), float(np.std(v))


def compare(m: Measures, reference: dict[str, Any] | None = None) -> dict[str, Any]:
    """The comparison table (rows) and the histograms of every quantity (docs/fidelity.md)."""
    ref = reference if reference is not None else load_reference()
    r120 = ref["speed_limit_120_kmh"]
    rows: list[dict[str, Any]] = []
    hists: dict[str, dict[str, Any]] = {}
    for q in QUANTITIES:
        values = getattr(m, q.attribute)
        rq = r120.get(q.key, {})
        for cls in CLASSES:
            sel = np.ones(m.pieces, dtype=bool) if cls == "all" else (m.truck if cls == "truck" else ~m.truck)
            n, mean, median, sd = _stats(values[sel])
            if not q.mean:
                mean = sd = float("nan")
            row = {"quantity": q.title, "unit": q.unit, "class": cls, "n": n, "sim_mean": mean,
                   "sim_median": median, "sim_sd": sd, "highd_mean": None, "highd_median": None,
                   "highd_sd": None, "similarity": None}
            if q.key == "per_vehicle_mean_speed_mps":
                src = rq if cls == "all" else r120.get(cls, {}).get("mean_speed_mps", {})
                row.update(highd_mean=src.get("mean"), highd_median=src.get("p50"), highd_sd=src.get("sd"))
            elif cls == "all":
                row.update(highd_median=rq.get("median"))
            if cls == "all" and "counts" in rq:
                h = histogram_similarity(rq["counts"], rq["edges"], values[sel])
                ref_n = rq.get("n") or (r120.get("vehicles") if q.attribute == "mean_speed_mps" else None)
                h["highd_n"] = ref_n
                h["highd_share_outside"] = (1.0 - sum(rq["counts"]) / ref_n) if ref_n else None
                h["sim_share_outside"] = (1.0 - h["n_in_bins"] / h["n"]) if h["n"] else None
                hists[q.key] = {"title": q.title, "unit": q.unit, **h}
                row["similarity"] = h["similarity"]
            rows.append(row)
    lane_changes = lane_change_rates(m, ref)
    return {"rows": rows, "histograms": hists, "lane_changes": lane_changes, "pieces": m.pieces,
            "runs": m.runs, "citation": ref.get("citation", HIGHD_CITATION)}


def to_json(result: dict[str, Any]) -> str:
    """``result`` as JSON text, NaN and infinities written as null."""
    def clean(x: Any) -> Any:
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [clean(v) for v in x]
        if isinstance(x, (float, np.floating)):
            return float(x) if np.isfinite(x) else None
        if isinstance(x, np.integer):
            return int(x)
        return x

    return json.dumps(clean(result), indent=1, allow_nan=False)


def _length(option: str, text: str) -> float:
    """``text`` of ``option`` as a length > 0 (m); else a one-line InputError."""
    import math

    from evoscen_sim.errors import InputError

    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"{option} {text!r}: expected a length > 0 (m)")
    return value


def piece_config(piece_m: str = "420", min_piece_m: str | None = None, truck_length: str = "7",
                 include_sut: bool = False) -> PieceConfig:
    """The measurement of ``scripts/fidelity_highd.py``'s ``--piece-m``, ``--min-piece-m`` (default:
    ``piece_m``), ``--truck-length`` and ``--include-sut`` (texts, checked here: one-line InputError)."""
    from evoscen_sim.errors import InputError

    piece = _length("--piece-m", piece_m)
    min_piece = _length("--min-piece-m", min_piece_m) if min_piece_m is not None else piece
    if min_piece > piece:
        raise InputError(f"--min-piece-m {min_piece_m!r}: expected a length <= --piece-m ({piece:g} m)")
    return PieceConfig(piece_m=piece, min_piece_m=min_piece, truck_length_m=_length("--truck-length", truck_length),
                       include_sut=include_sut)


def write_results(result: dict[str, Any], out: Path) -> tuple[str, list[Path]]:
    """Write ``out/fidelity_highd.json``, ``out/fidelity_highd.md`` and the plots (:func:`plot_histograms`);
    the Markdown table and the plots' paths. A directory that cannot be written is one InputError line."""
    from evoscen_sim.errors import InputError

    table = markdown_table(result)
    try:
        out.mkdir(parents=True, exist_ok=True)
        (out / "fidelity_highd.json").write_text(to_json(result), encoding="utf-8")
        (out / "fidelity_highd.md").write_text(f"# Traffic against highD\n\n{table}\nhighD: {result['citation']}\n",
                                               encoding="utf-8")
        plots = plot_histograms(result, out)
    except OSError as exc:
        raise InputError(f"--out {out}: cannot write: {exc.strerror or exc}") from None
    return table, plots


def _density_bins(labels: Iterable[str]) -> list[tuple[str, float, float]]:
    out = []
    for label in labels:
        lo, _, hi = label.partition("-")
        out.append((label, float(lo), float(hi)))
    return out


def lane_change_rates(m: Measures, reference: dict[str, Any]) -> list[dict[str, Any]]:
    """Lane changes per vehicle-km: all, per class and per density bin (the reference's bins; a run
    whose density lies outside every bin counts under "other")."""
    r120 = reference["speed_limit_120_kmh"]
    allrec = reference.get("all_recordings", {}).get("lane_changes_per_vehicle_km", {})
    rows = []

    def rate(sel: np.ndarray) -> tuple[int, float, float]:
        km = float(np.sum(m.trip_km[sel]))
        lc = int(np.sum(m.trip_lane_changes[sel]))
        return lc, km, (lc / km if km > 0 else float("nan"))

    for cls in CLASSES:
        sel = np.ones(m.trip_km.shape, dtype=bool) if cls == "all" else (m.trip_truck if cls == "truck" else ~m.trip_truck)
        lc, km, r = rate(sel)
        ref = r120.get("lane_changes_per_vehicle_km") if cls == "all" else r120.get(cls, {}).get(
            "lane_changes_per_vehicle_km")
        rows.append({"group": cls, "lane_changes": lc, "vehicle_km": km, "sim_rate": r, "highd_rate": ref,
                     "highd_scope": "120 km/h recordings"})
    dens = m.trip_density()
    bins = _density_bins(allrec.get("by_density_veh_per_km_per_lane", {}).keys())
    matched = np.zeros(dens.shape, dtype=bool)
    for label, lo, hi in bins:
        sel = (dens >= lo) & (dens < hi)
        matched |= sel
        lc, km, r = rate(sel)
        rows.append({"group": f"density {label} veh/km/lane", "lane_changes": lc, "vehicle_km": km, "sim_rate": r,
                     "highd_rate": allrec["by_density_veh_per_km_per_lane"][label], "highd_scope": "all recordings"})
    if (~matched).any():
        lc, km, r = rate(~matched)
        rows.append({"group": "density outside the bins", "lane_changes": lc, "vehicle_km": km, "sim_rate": r,
                     "highd_rate": None, "highd_scope": ""})
    return rows


# ====================================================================== output


def _f(x: Any, digits: int = 2) -> str:
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "–"
    return f"{x:.{digits}f}"


def markdown_table(result: dict[str, Any]) -> str:
    """The comparison as two Markdown tables (distributions; lane changes)."""
    out = ["| quantity | class | n | sim mean | sim sd | sim median | highD mean | highD sd | highD median | S |",
           "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in result["rows"]:
        out.append(f"| {r['quantity']} ({r['unit']}) | {r['class']} | {r['n']} | {_f(r['sim_mean'])} | "
                   f"{_f(r['sim_sd'])} | {_f(r['sim_median'])} | {_f(r['highd_mean'])} | {_f(r['highd_sd'])} | "
                   f"{_f(r['highd_median'])} | {_f(r['similarity'], 3)} |")
    out += ["", "| lane changes per vehicle-km | lane changes | vehicle-km | sim | highD |", "|---|---:|---:|---:|---:|"]
    for r in result["lane_changes"]:
        ref = _f(r["highd_rate"], 3) + (f" ({r['highd_scope']})" if r["highd_rate"] is not None else "")
        out.append(f"| {r['group']} | {r['lane_changes']} | {r['vehicle_km']:.1f} | {_f(r['sim_rate'], 3)} | {ref} |")
    notes = []
    for h in result["histograms"].values():
        hs, ss = h.get("highd_share_outside"), h.get("sim_share_outside")
        if hs is not None or ss is not None:
            notes.append(f"- {h['title']}: outside the bins [{h['edges'][0]:g}, {h['edges'][-1]:g}] {h['unit']}: "
                         f"highD {_f(None if hs is None else 100 * hs, 1)} %, simulation "
                         f"{_f(None if ss is None else 100 * ss, 1)} %")
    return "\n".join(out + ([""] + notes if notes else [])) + "\n"


def plot_histograms(result: dict[str, Any], out_dir: Path) -> list[Path]:
    """One PNG per distribution: the simulation's histogram beside highD's (share per unit, so bins of
    different widths compare)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    piece_m = float(result.get("settings", {}).get("piece_m", PieceConfig.piece_m))
    for key, h in result["histograms"].items():
        edges = np.asarray(h["edges"])
        ref = np.asarray(h["highd_counts"], dtype=float)
        sim = np.asarray(h["sim_counts"], dtype=float)
        width = np.diff(edges)
        left = edges[:-1]
        fig, ax = plt.subplots(figsize=(8, 4.5), constrained_layout=True)
        # share per unit of the quantity (the bins may differ in width: TTC's do)
        ax.bar(left + 0.05 * width, ref / max(ref.sum(), 1.0) / width, width=0.45 * width, align="edge",
               label=f"highD, 120 km/h ({int(ref.sum())} vehicles in the bins)", color="tab:gray")
        ax.bar(left + 0.5 * width, sim / max(sim.sum(), 1.0) / width, width=0.45 * width, align="edge",
               label=f"simulation ({int(sim.sum())} pieces of {piece_m:g} m in the bins)", color="tab:blue")
        ax.set_xlabel(f"{h['title']} ({h['unit']})")
        ax.set_ylabel(f"share of the values in the bins per {h['unit']}")
        ax.set_title(f"{h['title']}: S = 1 - JS = {_f(h['similarity'], 3)}")
        ax.legend()
        fig.text(0.99, 0.01, "highD: Krajewski et al., ITSC 2018", ha="right", va="bottom", fontsize=7)
        path = out_dir / f"{key}.png"
        fig.savefig(path, dpi=100)
        plt.close(fig)
        written.append(path)
    return written
