"""Measured campaigns on disk: a manifest plus one time series per test point.

Format (documented for rig engineers in ``docs/discrepancy.md``)::

    CAMPAIGN/
      manifest.csv        one row per test point
      campaign.json       optional: {"name": ..., "description": ...}
      points/*.parquet    (or *.csv) one time series per test point

manifest.csv columns: ``id`` (unique text), ``kind`` (``torsional`` or ``ramp``),
``speed_rpm``, ``mean_torque_nm`` (nominal), ``file`` (relative path), ``sample_rate_hz``.
Time-series columns: ``time_s``, ``input_torque_nm``, ``output_torque_nm``,
``input_speed_rpm``, ``output_speed_rpm``; ramps also ``windup_deg`` (input flange
minus output transducer angle) or both ``input_flange_deg`` and ``output_flange_deg``.

:func:`read_campaign` checks everything and returns the valid points together with a
report listing every problem by file and field; it never modifies the folder.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field

import numpy as np

from dampersim.errors import InputError
from dampersim.fileio import write_parquet_atomic, write_text_atomic

MANIFEST = "manifest.csv"
MANIFEST_COLUMNS = ("id", "kind", "speed_rpm", "mean_torque_nm", "file", "sample_rate_hz")
KINDS = ("torsional", "ramp")
SERIES_COLUMNS = ("time_s", "input_torque_nm", "output_torque_nm", "input_speed_rpm", "output_speed_rpm")
#: shortest torsional record [s] and fewest revolutions for the order analysis
MIN_TORSIONAL_S = 0.5
MIN_REVOLUTIONS = 8
MIN_RAMP_S = 2.0
RATE_TOLERANCE = 0.01  # relative mismatch of the sample rate accepted
SPEED_TOLERANCE = 0.05  # relative mismatch of the mean speed accepted
TORQUE_TOLERANCE = (0.15, 25.0)  # (relative, absolute N m) mismatch of the mean torque (torsional)


@dataclass(frozen=True)
class Problem:
    """One thing wrong with a campaign: where (file, field), which point, what."""

    file: str
    field: str
    message: str
    point: str = ""

    def __str__(self):
        where = f"{self.file}" + (f" [{self.field}]" if self.field else "")
        return f"{where}: {self.message}"


@dataclass(frozen=True, eq=False)
class MeasuredPoint:
    """One valid test point. SI inside: speed [rad/s], torques [N m], windup [rad]."""

    id: str
    kind: str
    speed_rpm: float
    mean_torque_nm: float
    sample_rate_hz: float
    time: np.ndarray = field(repr=False)
    input_torque: np.ndarray = field(repr=False)
    output_torque: np.ndarray = field(repr=False)
    input_speed_rpm: np.ndarray = field(repr=False)
    output_speed_rpm: np.ndarray = field(repr=False)
    windup: np.ndarray | None = field(default=None, repr=False)
    file: str = ""

    @property
    def speed(self) -> float:
        return self.speed_rpm * math.pi / 30.0

    @property
    def duration(self) -> float:
        return float(self.time[-1] - self.time[0])


@dataclass(eq=False)
class Campaign:
    """Valid points of a campaign and the report of everything that was wrong."""

    path: str
    name: str
    points: list
    problems: list
    rows: int = 0
    description: str = ""  # campaign.json's "description" ("" without one)

    @property
    def torsional(self) -> list:
        return [p for p in self.points if p.kind == "torsional"]

    @property
    def ramps(self) -> list:
        return [p for p in self.points if p.kind == "ramp"]

    def report(self) -> dict:
        """JSON-ready validation report."""
        return {
            "campaign": self.name,
            "rows": self.rows,
            "valid_points": [p.id for p in self.points],
            "problems": [{"file": q.file, "field": q.field, "point": q.point, "message": q.message} for q in self.problems],
        }

    def report_text(self) -> str:
        lines = [f"campaign {self.name}: {len(self.points)} of {self.rows} test points valid"]
        lines += [f"  {q}" for q in self.problems]
        return "\n".join(lines)


def _read_table(path):
    import pandas as pd

    if path.lower().endswith(".parquet"):
        return pd.read_parquet(path)
    if path.lower().endswith(".csv"):
        return pd.read_csv(path)
    raise InputError(f"{path}: accepted file types are .csv and .parquet")


def _num(value):
    try:
        x = float(value)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def read_campaign(path, strict: bool = False) -> Campaign:
    """Read and validate the campaign in folder ``path``.

    Returns a :class:`Campaign` with the valid points and every problem found. A missing
    or unreadable manifest raises :class:`InputError`; so does ``strict`` when any problem
    was found. Nothing in the folder is written.
    """
    path = os.fspath(path)
    mpath = os.path.join(path, MANIFEST)
    if not os.path.isdir(path):
        raise InputError(f"campaign {path!r}: accepted is a folder holding {MANIFEST}")
    if not os.path.isfile(mpath):
        raise InputError(f"{mpath}: missing; a campaign folder needs {MANIFEST} with columns {', '.join(MANIFEST_COLUMNS)}")
    name = os.path.basename(os.path.abspath(path))
    description = ""
    meta_path = os.path.join(path, "campaign.json")
    if os.path.isfile(meta_path):
        try:
            with open(meta_path, encoding="utf-8") as fh:
                meta = json.load(fh)
            name = str(meta.get("name", name))
            description = str(meta.get("description", ""))
        except (OSError, ValueError, AttributeError):
            pass
    try:
        man = _read_table(mpath)
    except Exception as exc:  # noqa: BLE001 - any parse failure is reported as bad input
        raise InputError(f"{mpath}: not a readable CSV table ({exc})") from None
    problems = []
    missing = [c for c in MANIFEST_COLUMNS if c not in man.columns]
    if missing:
        problems.append(Problem(MANIFEST, ",".join(missing), f"missing column(s); required are {', '.join(MANIFEST_COLUMNS)}"))
        camp = Campaign(path, name, [], problems, rows=len(man), description=description)
        if strict:
            raise InputError(camp.report_text())
        return camp
    points = []
    seen = set()
    for i, row in man.iterrows():
        line = f"{MANIFEST} row {i + 2}"
        pid = str(row["id"]).strip() if row["id"] == row["id"] else ""
        bad = []
        if not pid:
            bad.append(Problem(line, "id", "empty id"))
        elif pid in seen:
            bad.append(Problem(line, "id", f"duplicate id {pid!r}", pid))
        seen.add(pid)
        kind = str(row["kind"]).strip().lower()
        if kind not in KINDS:
            bad.append(Problem(line, "kind", f"{row['kind']!r}: accepted is {' or '.join(KINDS)}", pid))
        rpm = _num(row["speed_rpm"])
        if rpm is None or not 100.0 <= rpm <= 10000.0:
            bad.append(Problem(line, "speed_rpm", f"{row['speed_rpm']!r}: accepted is a speed of 100-10000 rpm", pid))
        tq = _num(row["mean_torque_nm"])
        if tq is None or abs(tq) > 5000:
            bad.append(Problem(line, "mean_torque_nm", f"{row['mean_torque_nm']!r}: accepted is a finite torque within +-5000 N m", pid))
        fs = _num(row["sample_rate_hz"])
        if fs is None or not fs > 0:
            bad.append(Problem(line, "sample_rate_hz", f"{row['sample_rate_hz']!r}: accepted is a positive sample rate", pid))
        rel = str(row["file"]).strip() if row["file"] == row["file"] else ""
        fpath = os.path.join(path, rel)
        if not rel or not os.path.isfile(fpath):
            bad.append(Problem(rel or line, "file", "file listed in the manifest does not exist", pid))
        if bad:
            problems += bad
            continue
        pt, probs = _read_point(fpath, rel, pid, kind, rpm, tq, fs)
        problems += probs
        if pt is not None:
            points.append(pt)
    listed = {os.path.normpath(str(f)) for f in man["file"] if f == f}
    for sub, _dirs, files in os.walk(path):
        for f in files:
            rel = os.path.normpath(os.path.relpath(os.path.join(sub, f), path))
            if f.endswith((".csv", ".parquet")) and rel != MANIFEST and rel not in listed:
                problems.append(Problem(rel, "file", "time series not listed in the manifest (ignored)"))
    camp = Campaign(path, name, points, problems, rows=len(man), description=description)
    if strict and problems:
        raise InputError(camp.report_text())
    return camp


def paths_outside(path) -> list:
    """Manifest ``file`` entries of the campaign in folder ``path`` that lie outside the
    folder (absolute, or leaving it through ".." or a link): ``[(manifest row, entry), ...]``
    with the row numbered as in :func:`read_campaign`'s report. A missing or unreadable
    manifest gives ``[]`` (:func:`read_campaign` reports it); so do empty entries."""
    path = os.fspath(path)
    inside = os.path.realpath(path)
    try:
        man = _read_table(os.path.join(path, MANIFEST))
    except Exception:  # noqa: BLE001 - reported by read_campaign
        return []
    if "file" not in man.columns:
        return []
    out = []
    for i, value in enumerate(man["file"]):
        rel = str(value).strip() if value == value else ""
        if not rel:
            continue
        target = os.path.realpath(os.path.join(inside, rel))
        if os.path.isabs(rel) or os.path.commonpath([inside, target]) != inside:
            out.append((i + 2, rel))
    return out


def _read_point(fpath, rel, pid, kind, rpm, tq, fs):
    probs = []
    try:
        df = _read_table(fpath)
    except Exception as exc:  # noqa: BLE001
        return None, [Problem(rel, "", f"unreadable ({exc})", pid)]
    need = list(SERIES_COLUMNS)
    windup_cols = None
    if kind == "ramp":
        if "windup_deg" in df.columns:
            windup_cols = ("windup_deg",)
        elif "input_flange_deg" in df.columns and "output_flange_deg" in df.columns:
            windup_cols = ("input_flange_deg", "output_flange_deg")
        else:
            probs.append(Problem(rel, "windup_deg", "ramp needs windup_deg or input_flange_deg and output_flange_deg", pid))
    missing = [c for c in need if c not in df.columns]
    if missing:
        probs.append(Problem(rel, ",".join(missing), f"missing column(s); required are {', '.join(SERIES_COLUMNS)}", pid))
    if probs:
        return None, probs
    cols = need + list(windup_cols or ())
    arrays = {}
    for c in cols:
        try:
            a = np.asarray(df[c], dtype=float)
        except (TypeError, ValueError):
            probs.append(Problem(rel, c, "non-numeric values", pid))
            continue
        nbad = int(np.sum(~np.isfinite(a)))
        if nbad:
            first = int(np.flatnonzero(~np.isfinite(a))[0])
            probs.append(Problem(rel, c, f"{nbad} NaN/inf samples (first at row {first + 2})", pid))
        arrays[c] = a
    if probs:
        return None, probs
    t = arrays["time_s"]
    n = len(t)
    if n < 16 or np.any(np.diff(t) <= 0):
        return None, [Problem(rel, "time_s", "time stamps must increase strictly (and >= 16 samples)", pid)]
    dts = np.diff(t)
    fs_file = 1.0 / float(np.mean(dts))
    if np.max(np.abs(dts - np.mean(dts))) > 0.05 * np.mean(dts):
        probs.append(Problem(rel, "time_s", "sample interval is not constant (resample to a fixed rate)", pid))
    if abs(fs_file - fs) > RATE_TOLERANCE * fs:
        probs.append(Problem(rel, "sample_rate_hz", f"file samples at {fs_file:.6g} Hz, manifest says {fs:g} Hz", pid))
    dur = float(t[-1] - t[0])
    if kind == "torsional":
        need_s = max(MIN_TORSIONAL_S, MIN_REVOLUTIONS * 60.0 / rpm)
        if dur < need_s:
            probs.append(Problem(rel, "time_s", f"record of {dur:.3g} s is too short for the order analysis (need >= {need_s:.3g} s)", pid))
        if fs < 2.2 * 8 * rpm / 60.0:
            probs.append(Problem(rel, "sample_rate_hz", f"{fs:g} Hz cannot resolve order 8 at {rpm:g} rpm", pid))
        mean_in = float(np.mean(arrays["input_torque_nm"]))
        tol = max(TORQUE_TOLERANCE[0] * abs(tq), TORQUE_TOLERANCE[1])
        if abs(mean_in - tq) > tol:
            probs.append(Problem(rel, "input_torque_nm", f"mean {mean_in:.1f} N m disagrees with the manifest's {tq:g} N m", pid))
    elif dur < MIN_RAMP_S:
        probs.append(Problem(rel, "time_s", f"ramp record of {dur:.3g} s is too short (need >= {MIN_RAMP_S:g} s)", pid))
    sp = float(np.mean(arrays["input_speed_rpm"]))
    if abs(sp - rpm) > SPEED_TOLERANCE * rpm:
        probs.append(Problem(rel, "input_speed_rpm", f"mean {sp:.1f} rpm disagrees with the manifest's {rpm:g} rpm", pid))
    if probs:
        return None, probs
    windup = None
    if windup_cols:
        w = arrays[windup_cols[0]] if len(windup_cols) == 1 else arrays[windup_cols[0]] - arrays[windup_cols[1]]
        windup = np.radians(w)
    return MeasuredPoint(
        id=pid, kind=kind, speed_rpm=rpm, mean_torque_nm=tq, sample_rate_hz=fs, time=t - t[0],
        input_torque=arrays["input_torque_nm"], output_torque=arrays["output_torque_nm"],
        input_speed_rpm=arrays["input_speed_rpm"], output_speed_rpm=arrays["output_speed_rpm"],
        windup=windup, file=rel,
    ), []


def write_point(path, point, fmt: str = "parquet", columns: dict | None = None) -> dict:
    """Write one MeasuredPoint's series into campaign folder ``path`` (``points/ID.fmt``,
    float32 series and float64 time, atomic) and return its manifest row, with the extra
    manifest ``columns`` (readers ignore columns they do not know)."""
    import pandas as pd

    if fmt not in ("parquet", "csv"):
        raise InputError(f"format {fmt!r}: accepted is parquet or csv")
    os.makedirs(os.path.join(path, "points"), exist_ok=True)
    rel = f"points/{point.id}.{fmt}"
    cols = {
        "time_s": point.time,
        "input_torque_nm": point.input_torque,
        "output_torque_nm": point.output_torque,
        "input_speed_rpm": point.input_speed_rpm,
        "output_speed_rpm": point.output_speed_rpm,
    }
    if point.windup is not None:
        cols["windup_deg"] = np.degrees(point.windup)
    df = pd.DataFrame({k: np.asarray(v, dtype=np.float64 if k == "time_s" else np.float32) for k, v in cols.items()})
    if fmt == "parquet":
        write_parquet_atomic(df, os.path.join(path, rel))
    else:
        write_text_atomic(os.path.join(path, rel), df.to_csv(index=False, float_format="%.6g"))
    return {"id": point.id, "kind": point.kind, "speed_rpm": point.speed_rpm, "mean_torque_nm": point.mean_torque_nm,
            "file": rel, "sample_rate_hz": point.sample_rate_hz, **(columns or {})}


def write_manifest(path, rows, name: str = "", description: str = "", metadata: dict | None = None) -> None:
    """Write the manifest of ``rows`` (from :func:`write_point`, in order) and campaign.json
    (name, description and the further entries of ``metadata``) into folder ``path``."""
    import pandas as pd

    columns = list(MANIFEST_COLUMNS) + [c for c in dict.fromkeys(k for r in rows for k in r) if c not in MANIFEST_COLUMNS]
    write_text_atomic(os.path.join(path, MANIFEST), pd.DataFrame(list(rows), columns=columns).to_csv(index=False))
    meta = {"name": name or os.path.basename(os.path.abspath(path)), "description": description, **(metadata or {})}
    write_text_atomic(os.path.join(path, "campaign.json"), json.dumps(meta, indent=2))


def check_point(path, row) -> tuple:
    """Read back and check the point of manifest ``row`` in campaign folder ``path`` as
    :func:`read_campaign` does: (MeasuredPoint or None, [Problem])."""
    rel = str(row["file"])
    return _read_point(os.path.join(path, rel), rel, str(row["id"]), row["kind"], float(row["speed_rpm"]),
                       float(row["mean_torque_nm"]), float(row["sample_rate_hz"]))


def write_campaign(path, points, name: str = "", description: str = "", fmt: str = "parquet",
                   metadata: dict | None = None, point_columns: dict | None = None) -> None:
    """Write ``points`` (list of MeasuredPoint) as a campaign folder; every file atomic.

    Series are stored as float32 (``fmt`` 'parquet' or 'csv'). Existing files of the same
    names are replaced atomically; other files are left alone. ``metadata``: further
    entries of campaign.json (e.g. where the data came from); ``point_columns``: {point id:
    {column: value}}, extra manifest columns (readers ignore columns they do not know).
    """
    rows = [write_point(path, p, fmt, (point_columns or {}).get(p.id)) for p in points]
    write_manifest(path, rows, name, description, metadata)


__all__ = ["MANIFEST", "MANIFEST_COLUMNS", "SERIES_COLUMNS", "KINDS", "Problem", "MeasuredPoint", "Campaign",
           "read_campaign", "paths_outside", "write_campaign", "write_point", "write_manifest", "check_point"]
