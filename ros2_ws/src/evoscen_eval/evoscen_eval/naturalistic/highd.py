"""HighD-format recordings: loader, writer and HighD's neighbour relations.

A HighD recording ``NN`` is three CSV files in one directory (the format of the highD
dataset, highd-dataset.com; the dataset itself may not be redistributed, users bring their
own copy):

* ``NN_recordingMeta.csv``: one row — frame rate, speed limit, lane markings
  (``upperLaneMarkings`` / ``lowerLaneMarkings``: image y positions separated by ``;``) …
* ``NN_tracksMeta.csv``: one row per track — ``width`` (= vehicle LENGTH), ``height``
  (= vehicle WIDTH), frames, ``class``, ``drivingDirection`` (1: upper lanes, towards −x;
  2: lower lanes, towards +x) …
* ``NN_tracks.csv``: one row per track and frame (``frame`` counts from 1 at
  ``frameRate`` Hz): ``x``, ``y`` = the UPPER-LEFT corner of the bounding box in image
  coordinates (y points DOWN), ``width``/``height`` as above, velocities and accelerations
  (signed along image x/y), ``dhw``/``thw``/``ttc`` (0 when there is no preceding vehicle;
  ``ttc`` negative when the gap opens), ``precedingXVelocity``, the neighbour ids
  (0 = none) and ``laneId``.

Lane ids (HighD): ``laneId = 1 + the number of lane markings (upper then lower, top to
bottom of the image) above the vehicle's centre``; so with ``U`` upper and ``L`` lower
markings the upper lanes are ``2 .. U`` and the lower lanes ``U + 2 .. U + L``, while
``1`` (above the road), ``U + 1`` (the median) and ``U + L + 1`` (below) are outside every
driving lane (:meth:`HighDRecording.driving_lanes`).

The loader reads only the columns asked for (:data:`EXTRACTION_COLUMNS` by default) into
typed numpy arrays, in chunks of lines, so a full recording (~1 M rows) loads in seconds
with a small memory footprint. Missing files, missing columns and values of the wrong
type raise :class:`~evoscen_sim.errors.InputError` naming the file, the line and the
column.
"""

from __future__ import annotations

import contextlib
import csv
import io
import re
from dataclasses import dataclass, field
from itertools import islice
from pathlib import Path

import numpy as np
from evoscen_sim.limits import MAX_HIGHD_META_BYTES, MAX_HIGHD_TRACKS_BYTES, check_regular_file
from evoscen_sim.errors import InputError

#: Every column of a HighD ``NN_tracks.csv``, in HighD's order.
TRACK_COLUMNS: tuple[str, ...] = (
    "frame", "id", "x", "y", "width", "height", "xVelocity", "yVelocity", "xAcceleration",
    "yAcceleration", "frontSightDistance", "backSightDistance", "dhw", "thw", "ttc",
    "precedingXVelocity", "precedingId", "followingId", "leftPrecedingId", "leftAlongsideId",
    "leftFollowingId", "rightPrecedingId", "rightAlongsideId", "rightFollowingId", "laneId",
)
#: Track columns holding integers (frame numbers, ids, lane ids); loaded as int32.
INT_TRACK_COLUMNS: frozenset[str] = frozenset({
    "frame", "id", "precedingId", "followingId", "leftPrecedingId", "leftAlongsideId",
    "leftFollowingId", "rightPrecedingId", "rightAlongsideId", "rightFollowingId", "laneId",
})
#: Track columns that may hold ±inf (a headway or TTC that is unbounded); never NaN.
UNBOUNDED_TRACK_COLUMNS: frozenset[str] = frozenset({"thw", "ttc"})
#: The track columns behaviour extraction needs (the loader's default).
EXTRACTION_COLUMNS: tuple[str, ...] = (
    "frame", "id", "x", "y", "width", "height", "xVelocity", "dhw", "thw", "ttc",
    "precedingXVelocity", "precedingId", "laneId",
)
#: Every column of a HighD ``NN_tracksMeta.csv``, in HighD's order.
TRACKS_META_COLUMNS: tuple[str, ...] = (
    "id", "width", "height", "initialFrame", "finalFrame", "numFrames", "class",
    "drivingDirection", "traveledDistance", "minXVelocity", "maxXVelocity", "meanXVelocity",
    "minDHW", "minTHW", "minTTC", "numLaneChanges",
)
#: tracksMeta columns the loader requires.
REQUIRED_TRACKS_META: tuple[str, ...] = (
    "id", "width", "height", "initialFrame", "finalFrame", "class", "drivingDirection",
)
#: Extra tracksMeta columns written by evoscen's exporter (ignored by HighD tooling, which
#: reads columns by name): the simulator's vehicle id and role (0 = BV, 1 = SUT).
EVOSCEN_META_COLUMNS: tuple[str, ...] = ("evoscenVehicleId", "evoscenRole")
_INT_META = frozenset({"id", "initialFrame", "finalFrame", "numFrames", "drivingDirection",
                       "numLaneChanges", "evoscenVehicleId", "evoscenRole"})
#: Every column of a HighD ``NN_recordingMeta.csv``, in HighD's order.
RECORDING_META_COLUMNS: tuple[str, ...] = (
    "id", "frameRate", "locationId", "speedLimit", "month", "weekDay", "startTime", "duration",
    "totalDrivenDistance", "totalDrivenTime", "numVehicles", "numCars", "numTrucks",
    "upperLaneMarkings", "lowerLaneMarkings",
)
REQUIRED_RECORDING_META: tuple[str, ...] = ("id", "frameRate", "upperLaneMarkings", "lowerLaneMarkings")

#: Lines parsed per chunk by the tracks loader.
CHUNK_LINES = 200_000

_RECORDING_RE = re.compile(r"^(\d+)_tracks\.csv$")


@dataclass
class HighDRecording:
    """One HighD-format recording in memory.

    ``tracks`` maps HighD column names to one array per row (int32 for
    :data:`INT_TRACK_COLUMNS`, float64 otherwise); rows are sorted by track id, then frame.
    ``tracks_meta`` maps tracksMeta column names to one array per track (``class`` as str).
    Units are HighD's (m, m/s, m/s², s); positions in image coordinates (y down).
    """

    recording_id: int
    frame_rate_hz: float
    upper_lane_markings: np.ndarray
    """y of the upper carriageway's lane markings (m, image coordinates), top to bottom."""
    lower_lane_markings: np.ndarray
    """y of the lower carriageway's lane markings (m), top to bottom."""
    recording_meta: dict[str, str]
    """Every recordingMeta field as text (the writer writes these back)."""
    tracks_meta: dict[str, np.ndarray]
    tracks: dict[str, np.ndarray]
    source: str = "<memory>"
    """Where it came from (file stem or bag), for messages."""
    warnings: list[str] = field(default_factory=list)

    # ------------------------------------------------------------------ derived views
    @property
    def num_rows(self) -> int:
        """Number of (track, frame) rows."""
        return int(self.tracks["id"].shape[0]) if "id" in self.tracks else 0

    def _track_index(self, track_ids: np.ndarray) -> np.ndarray:
        """Index into ``tracks_meta`` of each of ``track_ids`` (all must exist)."""
        meta_ids = self.tracks_meta["id"]
        order = np.argsort(meta_ids, kind="stable")
        pos = np.searchsorted(meta_ids[order], track_ids)
        pos = np.clip(pos, 0, len(order) - 1)
        return order[pos]

    def row_meta(self, name: str) -> np.ndarray:
        """The tracksMeta column ``name`` broadcast to every tracks row (by track id)."""
        return self.tracks_meta[name][self._track_index(self.tracks["id"])]

    def driving_direction(self) -> np.ndarray:
        """drivingDirection of every row (1: upper lanes, −x; 2: lower lanes, +x)."""
        return self.row_meta("drivingDirection")

    def x_center(self) -> np.ndarray:
        """Box centre x of every row (m): ``x + width / 2`` (x is the upper-left corner)."""
        return self.tracks["x"] + 0.5 * self.tracks["width"]

    def y_center(self) -> np.ndarray:
        """Box centre y of every row (m, image coordinates): ``y + height / 2``."""
        return self.tracks["y"] + 0.5 * self.tracks["height"]

    def driving_lanes(self, direction: int) -> np.ndarray:
        """The laneIds of the driving lanes of ``direction`` (1 upper, 2 lower).

        Upper: ``2 .. U``; lower: ``U + 2 .. U + L`` (``U``, ``L`` = numbers of upper and
        lower markings); every other id is outside the driving lanes.
        """
        u, low = len(self.upper_lane_markings), len(self.lower_lane_markings)
        if direction == 1:
            return np.arange(2, u + 1, dtype=np.int32)
        return np.arange(u + 2, u + low + 1, dtype=np.int32)

    def lane_id_at(self, y_center: np.ndarray) -> np.ndarray:
        """HighD laneId of image positions ``y_center``: 1 + the number of markings at or above it."""
        marks = np.sort(np.concatenate([self.upper_lane_markings, self.lower_lane_markings]))
        return (1 + np.searchsorted(marks, np.asarray(y_center, dtype=np.float64), side="right")).astype(np.int32)


# ====================================================================== loading


def find_recordings(directory: Path | str) -> list[str]:
    """The recording ids (``"01"``, ``"02"`` …) with an ``NN_tracks.csv`` in ``directory``."""
    d = Path(directory)
    if not d.is_dir():
        raise InputError(f"HighD directory {str(d)!r}: not a directory")
    return sorted((m.group(1) for p in d.iterdir() if (m := _RECORDING_RE.match(p.name))), key=int)


def recording_paths(directory: Path | str, recording: str | int) -> dict[str, Path]:
    """The three file paths of recording ``recording`` (``1`` and ``"01"`` both give ``01_*``)."""
    rid = f"{int(recording):02d}" if str(recording).isdigit() else str(recording)
    d = Path(directory)
    return {
        "recordingMeta": d / f"{rid}_recordingMeta.csv",
        "tracksMeta": d / f"{rid}_tracksMeta.csv",
        "tracks": d / f"{rid}_tracks.csv",
    }


def _open_text(path: Path, limit: int = MAX_HIGHD_META_BYTES):
    """The CSV file opened as UTF-8 text, after checking it is a regular file of at most ``limit``
    bytes (docs/input-limits.md); read it inside :func:`_utf8_errors`."""
    if not Path(path).exists():
        raise InputError(f"{path}: file not found (a HighD recording needs NN_recordingMeta.csv, "
                         "NN_tracksMeta.csv and NN_tracks.csv)")
    check_regular_file(path, str(path), "HighD file", limit)
    try:
        return open(path, encoding="utf-8", newline="")
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror or exc}") from None


@contextlib.contextmanager
def _utf8_errors(path: Path):
    """A UnicodeDecodeError while reading ``path`` (a binary file) becomes one InputError line."""
    try:
        yield
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not UTF-8 text ({exc.reason}); expected a HighD CSV text file") from None


def _header(path: Path, line: str, required: tuple[str, ...] | list[str], known: tuple[str, ...]) -> list[str]:
    names = [h.strip().lstrip("\ufeff") for h in line.rstrip("\r\n").split(",")]
    if not line.strip():
        raise InputError(f"{path}: empty file (expected a header line with the columns {', '.join(known)})")
    for col in required:
        if col not in names:
            raise InputError(f"{path}: missing column {col!r} (expected HighD columns: {', '.join(known)})")
    return names


def _parse_number(path: Path, line_no: int, column: str, text: str, *, integer: bool, allow_inf: bool = False) -> float:
    try:
        value = float(text)
    except ValueError:
        kind = "an integer" if integer else "a number"
        raise InputError(f"{path}: line {line_no}: column {column!r}: {text.strip()!r} is not {kind}") from None
    if np.isnan(value) or (np.isinf(value) and not allow_inf):
        raise InputError(f"{path}: line {line_no}: column {column!r}: {text.strip()!r} is not a finite number")
    if integer and value != int(value):
        raise InputError(f"{path}: line {line_no}: column {column!r}: {text.strip()!r} is not an integer")
    return value


def _parse_markings(path: Path, column: str, text: str) -> np.ndarray:
    parts = [p for p in text.strip().split(";") if p.strip()]
    if not parts:
        raise InputError(f"{path}: column {column!r}: {text!r} has no lane markings "
                         "(expected y positions separated by ';', e.g. '8.51;12.59;16.43')")
    vals = np.array([_parse_number(path, 2, column, p, integer=False) for p in parts])
    if np.any(np.diff(vals) <= 0):
        raise InputError(f"{path}: column {column!r}: {text!r}: lane markings must increase (top to bottom)")
    return vals


def load_recording_meta(path: Path) -> tuple[dict[str, str], int, float, np.ndarray, np.ndarray]:
    """Read ``NN_recordingMeta.csv``: (raw fields, id, frame rate, upper, lower markings)."""
    with _open_text(path) as f, _utf8_errors(path):
        rows = list(csv.reader(f))
    if not rows:
        raise InputError(f"{path}: empty file (expected a header and one row)")
    names = _header(path, ",".join(rows[0]), REQUIRED_RECORDING_META, RECORDING_META_COLUMNS)
    if len(rows) < 2 or not any(c.strip() for c in rows[1]):
        raise InputError(f"{path}: no data row (expected one row after the header)")
    if len(rows[1]) != len(names):
        raise InputError(f"{path}: line 2 has {len(rows[1])} fields, the header {len(names)}")
    raw = dict(zip(names, (c.strip() for c in rows[1])))
    rid = int(_parse_number(path, 2, "id", raw["id"], integer=True))
    rate = _parse_number(path, 2, "frameRate", raw["frameRate"], integer=False)
    if rate <= 0:
        raise InputError(f"{path}: line 2: column 'frameRate': {raw['frameRate']!r} must be > 0")
    upper = _parse_markings(path, "upperLaneMarkings", raw["upperLaneMarkings"])
    lower = _parse_markings(path, "lowerLaneMarkings", raw["lowerLaneMarkings"])
    return raw, rid, rate, upper, lower


def load_tracks_meta(path: Path) -> dict[str, np.ndarray]:
    """Read ``NN_tracksMeta.csv`` (every standard column present, and evoscen's extras)."""
    with _open_text(path) as f, _utf8_errors(path):
        reader = csv.reader(f)
        try:
            header = next(reader)
        except StopIteration:
            header = []
        names = _header(path, ",".join(header), REQUIRED_TRACKS_META, TRACKS_META_COLUMNS)
        wanted = [c for c in (*TRACKS_META_COLUMNS, *EVOSCEN_META_COLUMNS) if c in names]
        idx = {c: names.index(c) for c in wanted}
        cols: dict[str, list] = {c: [] for c in wanted}
        for line_no, row in enumerate(reader, start=2):
            if not any(c.strip() for c in row):
                continue
            if len(row) != len(names):
                raise InputError(f"{path}: line {line_no} has {len(row)} fields, the header {len(names)}")
            for c in wanted:
                text = row[idx[c]]
                if c == "class":
                    cols[c].append(text.strip())
                else:
                    cols[c].append(_parse_number(path, line_no, c, text, integer=c in _INT_META,
                                                 allow_inf=c in ("minTHW", "minTTC")))
    out: dict[str, np.ndarray] = {}
    for c, vals in cols.items():
        if c == "class":
            out[c] = np.array(vals, dtype=str)
        elif c in _INT_META:
            out[c] = np.array(vals, dtype=np.int64).astype(np.int32)
        else:
            out[c] = np.array(vals, dtype=np.float64)
    bad = np.flatnonzero(~np.isin(out["drivingDirection"], (1, 2)))
    if bad.size:
        raise InputError(f"{path}: line {bad[0] + 2}: column 'drivingDirection': "
                         f"{out['drivingDirection'][bad[0]]} (expected 1 (upper lanes) or 2 (lower lanes))")
    ids, counts = np.unique(out["id"], return_counts=True)
    if np.any(counts > 1):
        raise InputError(f"{path}: column 'id': track id {ids[counts > 1][0]} appears more than once")
    return out


def _locate_bad_value(path: Path, lines: list[str], first_line_no: int, names: list[str],
                      columns: tuple[str, ...], idx: list[int]) -> InputError:
    """The InputError for the first malformed line of a chunk that numpy refused."""
    for j, line in enumerate(lines):
        if not line.strip():
            continue
        fields = line.rstrip("\r\n").split(",")
        if len(fields) != len(names):
            return InputError(f"{path}: line {first_line_no + j} has {len(fields)} fields, the header {len(names)}")
        for c, i in zip(columns, idx):
            _parse_number(path, first_line_no + j, c, fields[i], integer=c in INT_TRACK_COLUMNS,
                          allow_inf=c in UNBOUNDED_TRACK_COLUMNS)
    return InputError(f"{path}: lines {first_line_no}..{first_line_no + len(lines) - 1}: unreadable values")


def load_tracks(path: Path, columns: tuple[str, ...] = EXTRACTION_COLUMNS,
                chunk_lines: int = CHUNK_LINES) -> dict[str, np.ndarray]:
    """Read the ``columns`` of ``NN_tracks.csv``, ``chunk_lines`` lines at a time.

    Integer columns become int32, the others float64. Raises InputError naming the file,
    line and column for a missing column, a non-numeric or non-integer value, or NaN.
    """
    unknown = [c for c in columns if c not in TRACK_COLUMNS]
    if unknown:
        raise InputError(f"{path}: {unknown[0]!r} is not a HighD tracks column (expected one of {', '.join(TRACK_COLUMNS)})")
    with _open_text(path, MAX_HIGHD_TRACKS_BYTES) as f, _utf8_errors(path):
        names = _header(path, f.readline(), columns, TRACK_COLUMNS)
        idx = [names.index(c) for c in columns]
        commas = len(names) - 1
        parts: list[np.ndarray] = []
        line_no = 2
        while True:
            lines = list(islice(f, chunk_lines))
            if not lines:
                break
            ragged = next((j for j, line in enumerate(lines) if line.count(",") != commas and line.strip()), None)
            if ragged is not None:
                raise _locate_bad_value(path, lines[ragged:ragged + 1], line_no + ragged, names, columns, idx)
            try:
                block = np.loadtxt(lines, delimiter=",", usecols=idx, dtype=np.float64, ndmin=2, comments=None)
            except ValueError:
                raise _locate_bad_value(path, lines, line_no, names, columns, idx) from None
            nonfinite = ~np.isfinite(block)
            if nonfinite.any():
                for k, c in enumerate(columns):
                    col_bad = np.isnan(block[:, k]) if c in UNBOUNDED_TRACK_COLUMNS else nonfinite[:, k]
                    if col_bad.any():
                        raise _locate_bad_value(path, lines, line_no, names, columns, idx)
            parts.append(block)
            line_no += len(lines)
    data = np.concatenate(parts) if parts else np.zeros((0, len(columns)))
    del parts
    out: dict[str, np.ndarray] = {}
    for k, c in enumerate(columns):
        col = data[:, k]
        if c in INT_TRACK_COLUMNS:
            bad = np.flatnonzero(col != np.round(col))
            if bad.size:
                raise InputError(f"{path}: line {bad[0] + 2}: column {c!r}: {col[bad[0]]:g} is not an integer")
            out[c] = col.astype(np.int32)
        else:
            out[c] = col.copy()
    return out


def load_recording(directory: Path | str, recording: str | int,
                   columns: tuple[str, ...] = EXTRACTION_COLUMNS) -> HighDRecording:
    """Load recording ``recording`` (e.g. ``"01"``) of the HighD directory ``directory``.

    Only the tracks ``columns`` are read (``TRACK_COLUMNS`` for all). Rows are returned
    sorted by track id, then frame (HighD's own order; re-sorted if a file is not).
    """
    paths = recording_paths(directory, recording)
    raw, rid, rate, upper, lower = load_recording_meta(paths["recordingMeta"])
    meta = load_tracks_meta(paths["tracksMeta"])
    cols = tuple(dict.fromkeys(("frame", "id", *columns)))
    tracks = load_tracks(paths["tracks"], cols)
    # every track id must be described in tracksMeta
    known = np.isin(tracks["id"], meta["id"])
    if not known.all():
        bad = int(np.flatnonzero(~known)[0])
        raise InputError(f"{paths['tracks']}: line {bad + 2}: column 'id': track {tracks['id'][bad]} is not in "
                         f"{paths['tracksMeta'].name}")
    key_sorted = (np.all(np.diff(tracks["id"]) >= 0)
                  and np.all((np.diff(tracks["frame"]) > 0) | (np.diff(tracks["id"]) > 0)))
    if not key_sorted:
        order = np.lexsort((tracks["frame"], tracks["id"]))
        tracks = {c: a[order] for c, a in tracks.items()}
    return HighDRecording(recording_id=rid, frame_rate_hz=rate, upper_lane_markings=upper,
                          lower_lane_markings=lower, recording_meta=raw, tracks_meta=meta, tracks=tracks,
                          source=str(paths["tracks"]))


# ====================================================================== writing

#: printf format of each written tracks column: HighD-like precision (mm, mm/s).
def _track_format(column: str) -> str:
    return "%d" if column in INT_TRACK_COLUMNS else "%.3f"


def _write_csv_block(f: io.TextIOBase, columns: tuple[str, ...], arrays: dict[str, np.ndarray], rows: int,
                     chunk: int = 100_000) -> None:
    fmt = ",".join(_track_format(c) for c in columns)
    for start in range(0, rows, chunk):
        stop = min(rows, start + chunk)
        # + 0.0 turns -0.0 into 0.0, so a zero is never written as "-0.000"
        block = np.column_stack([arrays[c][start:stop].astype(np.float64) for c in columns]) + 0.0
        np.savetxt(f, block, fmt=fmt, delimiter=",")


def _meta_text(column: str, value: object) -> str:
    if isinstance(value, (str, np.str_)):
        return str(value)
    if column in _INT_META:
        return str(int(value))
    v = float(value)
    return "inf" if np.isinf(v) and v > 0 else ("-inf" if np.isinf(v) else f"{v:.3f}")


def write_recording(directory: Path | str, rec: HighDRecording, *, overwrite: bool = False) -> dict[str, Path]:
    """Write ``rec`` as ``NN_recordingMeta.csv``, ``NN_tracksMeta.csv``, ``NN_tracks.csv``.

    ``rec`` must hold every HighD column (tracks: :data:`TRACK_COLUMNS`; tracksMeta:
    :data:`TRACKS_META_COLUMNS`, evoscen's extra columns when present; recordingMeta:
    :data:`RECORDING_META_COLUMNS`). Existing files are kept unless ``overwrite``.
    """
    d = Path(directory)
    paths = recording_paths(d, rec.recording_id)
    for c in TRACK_COLUMNS:
        if c not in rec.tracks:
            raise ValueError(f"write_recording: the recording has no tracks column {c!r}")
    for c in TRACKS_META_COLUMNS:
        if c not in rec.tracks_meta:
            raise ValueError(f"write_recording: the recording has no tracksMeta column {c!r}")
    for c in RECORDING_META_COLUMNS:
        if c not in rec.recording_meta:
            raise ValueError(f"write_recording: the recording has no recordingMeta field {c!r}")
    for c in TRACK_COLUMNS:
        col = np.asarray(rec.tracks[c])
        if col.dtype.kind == "f" and not np.isfinite(col).all():
            i = int(np.flatnonzero(~np.isfinite(col))[0])
            raise InputError(f"{paths['tracks']}: column {c!r} row {i + 1} (track {int(rec.tracks['id'][i])}, frame "
                             f"{int(rec.tracks['frame'][i])}) is {col[i]}: HighD files hold finite values only; not written")
    for c in TRACKS_META_COLUMNS:
        col = np.asarray(rec.tracks_meta[c])
        if col.dtype.kind == "f" and np.isnan(col).any():
            i = int(np.flatnonzero(np.isnan(col))[0])
            raise InputError(f"{paths['tracksMeta']}: column {c!r} row {i + 1} is nan: not written")
    if not overwrite:
        for p in paths.values():
            if p.exists():
                raise InputError(f"{p}: already exists (choose another directory or recording id, or overwrite)")
    try:
        d.mkdir(parents=True, exist_ok=True)
        with open(paths["recordingMeta"], "w", encoding="utf-8", newline="") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(RECORDING_META_COLUMNS)
            w.writerow([rec.recording_meta[c] for c in RECORDING_META_COLUMNS])
        meta_cols = [*TRACKS_META_COLUMNS, *(c for c in EVOSCEN_META_COLUMNS if c in rec.tracks_meta)]
        with open(paths["tracksMeta"], "w", encoding="utf-8", newline="") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(meta_cols)
            for i in range(len(rec.tracks_meta["id"])):
                w.writerow([_meta_text(c, rec.tracks_meta[c][i]) for c in meta_cols])
        with open(paths["tracks"], "w", encoding="utf-8", newline="") as f:
            f.write(",".join(TRACK_COLUMNS) + "\n")
            _write_csv_block(f, TRACK_COLUMNS, rec.tracks, rec.num_rows)
    except OSError as exc:
        raise InputError(f"{d}: cannot write the HighD files: {exc.strerror or exc}") from None
    return paths


# ====================================================================== neighbours


@dataclass
class Neighbours:
    """Row index (−1 = none) of each row's neighbours in the same frame (HighD's relations)."""

    preceding: np.ndarray
    following: np.ndarray
    left_preceding: np.ndarray
    left_alongside: np.ndarray
    left_following: np.ndarray
    right_preceding: np.ndarray
    right_alongside: np.ndarray
    right_following: np.ndarray


def find_neighbours(frame: np.ndarray, lane_id: np.ndarray, x_center: np.ndarray, length: np.ndarray,
                    direction: np.ndarray) -> Neighbours:
    """HighD's neighbour relations of every row, vectorized over all rows at once.

    Rows are (track, frame) states. Along the direction of travel (``u = x`` for direction
    2, ``−x`` for direction 1):

    * preceding / following: the nearest vehicle with its centre ahead / behind in the same
      lane (same ``frame`` and ``lane_id``);
    * left / right lane: ``laneId − 1`` / ``+ 1`` for direction 2 and the reverse for
      direction 1 (image y points down, so "left" of a vehicle driving towards −x is +y);
      there, the nearest vehicle whose body overlaps the ego's longitudinally is
      *alongside* (one at most), the nearest one entirely ahead *preceding*, the nearest one
      entirely behind *following*.

    One lexicographic sort of all rows by (frame, lane, u), then ``searchsorted``: O(R log R).
    """
    n = frame.shape[0]
    none = np.full(n, -1, dtype=np.int64)
    if n == 0:
        return Neighbours(*(none.copy() for _ in range(8)))
    u = np.where(direction == 1, -x_center, x_center).astype(np.float64)
    half = 0.5 * length.astype(np.float64)
    lanes_span = int(lane_id.max()) + 3  # room for lane ± 1 without colliding blocks
    block = frame.astype(np.int64) * lanes_span + (lane_id.astype(np.int64) + 1)
    u0 = float(u.min())
    scale = float(u.max() - u0) + 1.0
    key = block.astype(np.float64) * scale + (u - u0)
    order = np.lexsort((u, block))
    key_s = key[order]
    block_s = block[order]
    pos = np.empty(n, dtype=np.int64)
    pos[order] = np.arange(n)

    # same lane: the next / previous row of the sorted order in the same block
    nxt = pos + 1
    prv = pos - 1
    has_next = (nxt < n) & (block_s[np.minimum(nxt, n - 1)] == block)
    has_prev = (prv >= 0) & (block_s[np.maximum(prv, 0)] == block)
    preceding = np.where(has_next, order[np.minimum(nxt, n - 1)], -1)
    following = np.where(has_prev, order[np.maximum(prv, 0)], -1)

    def side(delta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        other = block + delta
        k = np.searchsorted(key_s, other.astype(np.float64) * scale + (u - u0), side="left")

        def row_at(p: np.ndarray) -> np.ndarray:
            ok = (p >= 0) & (p < n)
            pc = np.clip(p, 0, n - 1)
            ok &= block_s[pc] == other
            return np.where(ok, order[pc], -1)

        ahead, ahead2 = row_at(k), row_at(k + 1)
        behind, behind2 = row_at(k - 1), row_at(k - 2)
        front, rear = u + half, u - half

        def overlaps(r: np.ndarray) -> np.ndarray:
            rc = np.maximum(r, 0)
            return (r >= 0) & (u[rc] - half[rc] <= front) & (u[rc] + half[rc] >= rear)

        ov_a, ov_b = overlaps(ahead), overlaps(behind)
        # alongside: the nearer overlapping one of the two centre-neighbours
        da = np.abs(u[np.maximum(ahead, 0)] - u)
        db = np.abs(u[np.maximum(behind, 0)] - u)
        alongside = np.where(ov_a & (~ov_b | (da <= db)), ahead, np.where(ov_b, behind, -1))
        prec = np.where(ov_a, np.where(overlaps(ahead2), -1, ahead2), ahead)
        foll = np.where(ov_b, np.where(overlaps(behind2), -1, behind2), behind)
        return prec, alongside, foll

    left_delta = np.where(direction == 1, 1, -1).astype(np.int64)
    lp, la, lf = side(left_delta)
    rp, ra, rf = side(-left_delta)
    return Neighbours(preceding, following, lp, la, lf, rp, ra, rf)
