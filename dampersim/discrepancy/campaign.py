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

import io
import json
import math
import os
from dataclasses import dataclass, field

import numpy as np

from dampersim.analysis.ordertrack import check_speed
from dampersim.errors import InputError

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


#: Largest manifest.csv read at all [bytes] (4 MB holds some 40 000 rows of this format).
MAX_MANIFEST_BYTES = 4 * 2**20
#: Most columns a manifest may have (six are used; readers ignore the others).
MAX_MANIFEST_COLUMNS = 64
#: Largest Parquet footer read [bytes]: the footer holds the schema and the row-group
#: directory, a few kB for a time series; a forged one could claim gigabytes.
MAX_PARQUET_FOOTER_BYTES = 1 * 2**20
#: Longest CSV header line read [bytes].
MAX_CSV_HEADER_BYTES = 64 * 2**10


@dataclass(frozen=True)
class CampaignLimits:
    """Caps checked by :func:`scan_campaign` from metadata alone, before any time series is
    loaded (``None``: no cap). The dashboard's uploads use
    :data:`dampersim.discrepancy.upload.UPLOAD_LIMITS`; the command line reads campaigns
    without caps.

    ``rows``: manifest rows (test points); ``samples_per_file`` and ``total_samples``:
    rows of the time series (one sample of every column); ``record_s``: seconds of one
    record (its rows over its manifest sample rate); ``total_record_s``: seconds of all
    records together, the measure of the diagnosis's cost (every record is simulated);
    ``bytes_per_sample``: the uncompressed size of one Parquet row, or the average length
    of a CSV line; ``columns``: columns of a time-series file.
    """

    rows: int | None = None
    samples_per_file: int | None = None
    total_samples: int | None = None
    record_s: float | None = None
    total_record_s: float | None = None
    bytes_per_sample: int | None = None
    columns: int | None = None


def _manifest_bytes(mpath) -> bytes:
    """The manifest's bytes, refused above :data:`MAX_MANIFEST_BYTES`."""
    try:
        with open(mpath, "rb") as fh:
            data = fh.read(MAX_MANIFEST_BYTES + 1)
    except OSError as exc:
        raise InputError(f"{MANIFEST}: not readable ({exc.strerror or exc})") from None
    if len(data) > MAX_MANIFEST_BYTES:
        raise InputError(f"{MANIFEST} is larger than {MAX_MANIFEST_BYTES // 2**20} MB; accepted is a table of one row per "
                         f"test point with the columns {', '.join(MANIFEST_COLUMNS)}")
    return data


def read_manifest(mpath, limits: CampaignLimits | None = None):
    """manifest.csv as a DataFrame of text (empty cells: NaN): bounded in bytes and columns
    before it is parsed, and in rows by ``limits.rows``. InputError names the file, the
    count found and the limit."""
    import pandas as pd

    data = _manifest_bytes(mpath)
    header = data.split(b"\n", 1)[0]
    ncols = header.count(b",") + 1
    if ncols > MAX_MANIFEST_COLUMNS:
        raise InputError(f"{MANIFEST}: {ncols} columns in the header; accepted are at most {MAX_MANIFEST_COLUMNS} "
                         f"(required: {', '.join(MANIFEST_COLUMNS)})")
    try:
        man = pd.read_csv(io.BytesIO(data), dtype=str, keep_default_na=False, na_values=[""],
                          encoding="utf-8", on_bad_lines="error")
    except Exception as exc:  # noqa: BLE001 - any parse failure is reported as bad input
        raise InputError(f"{MANIFEST}: not a readable CSV table ({_short(exc)})") from None
    if limits is not None and limits.rows is not None and len(man) > limits.rows:
        raise InputError(f"{MANIFEST}: {len(man)} rows (test points); accepted are at most {limits.rows} here "
                         "(diagnose larger campaigns with python -m dampersim diagnose CAMPAIGN)")
    if "file" in man.columns:  # a control character (NUL above all) is no file name on any system
        for i, rel in enumerate(man["file"].tolist()):
            if any(ord(ch) < 32 for ch in _cell(rel)):
                raise InputError(f"{MANIFEST} row {i + 2}: the file name {_cell(rel)!r} contains a control character; "
                                 "accepted is a relative path such as points/p01.parquet")
    return man


def _short(exc) -> str:
    text = " ".join(str(exc).split())
    return text if len(text) <= 200 else text[:200] + "…"


def _cell(value) -> str:
    """A manifest cell as stripped text ("" when empty)."""
    return str(value).strip() if value == value and value is not None else ""


def repeated_files(man) -> dict:
    """{file entry: [manifest rows]} of the files a manifest lists more than once (entries
    compared after normalising the path; rows numbered as in :func:`read_campaign`)."""
    rows: dict = {}
    if "file" not in man.columns:
        return {}
    for i, value in enumerate(man["file"]):
        rel = _cell(value)
        if rel:
            rows.setdefault(os.path.normpath(rel.replace("\\", "/")), []).append(i + 2)
    return {k: v for k, v in rows.items() if len(v) > 1}


def _rows_text(rows) -> str:
    shown = ", ".join(str(r) for r in rows[:10])
    return shown + (f" and {len(rows) - 10} more" if len(rows) > 10 else "")


def file_shape(fpath, rel: str = "", max_lines: int | None = None) -> dict:
    """Rows, columns and uncompressed bytes of a time-series file from its metadata, no data
    loaded: the Parquet footer (its length checked first) or the CSV header line and a line
    count that stops after ``max_lines`` lines (``rows`` is then ``max_lines + 1``, i.e.
    "more than"). Returns {"rows", "columns" (names), "bytes", "more"}; InputError for a
    file that is neither, or a damaged one (a Parquet file whose file-level row count
    differs from the sum over its row groups included)."""
    rel = rel or os.path.basename(fpath)
    low = fpath.lower()
    if low.endswith(".parquet"):
        import pyarrow.parquet as pq

        try:
            size = os.path.getsize(fpath)
            with open(fpath, "rb") as fh:
                if size < 12:
                    raise ValueError("too short")
                fh.seek(size - 8)
                tail = fh.read(8)
            if tail[4:] != b"PAR1":
                raise ValueError("no Parquet footer")
            footer = int.from_bytes(tail[:4], "little")
            if footer > MAX_PARQUET_FOOTER_BYTES or footer > size - 12:
                raise InputError(f"{rel}: a Parquet footer of {footer} bytes; accepted is at most "
                                 f"{MAX_PARQUET_FOOTER_BYTES // 2**20} MB of metadata")
            meta = pq.ParquetFile(fpath, memory_map=False).metadata
            names = [meta.schema.column(i).name for i in range(meta.num_columns)]
            groups = [meta.row_group(i) for i in range(meta.num_row_groups)]
            nbytes = sum(g.total_byte_size for g in groups)
            rows = sum(int(g.num_rows) for g in groups)  # what a reader loads, whatever the file-level count says
            if rows != int(meta.num_rows):
                raise InputError(f"{rel}: the Parquet footer gives {int(meta.num_rows)} rows but its row groups hold "
                                 f"{rows}; accepted is a file whose row count matches its row groups (this one is "
                                 "damaged or crafted)")
            return {"rows": rows, "columns": names, "bytes": int(nbytes), "more": False}
        except InputError:
            raise
        except Exception as exc:  # noqa: BLE001 - a damaged file is bad input
            raise InputError(f"{rel}: not a readable Parquet file ({_short(exc)})") from None
    if low.endswith(".csv"):
        try:
            size = os.path.getsize(fpath)
            with open(fpath, "rb") as fh:
                header = fh.readline(MAX_CSV_HEADER_BYTES + 1)
                if len(header) > MAX_CSV_HEADER_BYTES:
                    raise InputError(f"{rel}: a header line longer than {MAX_CSV_HEADER_BYTES // 1024} kB; accepted is one "
                                     "line of column names")
                lines, tail = 0, b"\n"
                while chunk := fh.read(2**20):
                    lines += chunk.count(b"\n")
                    tail = chunk[-1:]
                    if max_lines is not None and lines > max_lines:
                        break
                else:
                    lines += tail != b"\n"  # a last line without a newline
        except OSError as exc:
            raise InputError(f"{rel}: not readable ({exc.strerror or exc})") from None
        names = [c.strip().strip('"') for c in header.decode("utf-8", "replace").rstrip("\r\n").split(",")]
        more = max_lines is not None and lines > max_lines
        return {"rows": lines, "columns": names, "bytes": size, "more": more}
    raise InputError(f"{rel}: accepted file types are .csv and .parquet")


def scan_campaign(path, limits: CampaignLimits) -> dict:
    """Check the campaign in folder ``path`` against ``limits`` from metadata alone: the
    manifest (bounded bytes, columns and rows), repeated file references, and each listed
    file's rows, columns and size from its Parquet footer or CSV header and line count. No
    time series is loaded, so a small file that would expand to gigabytes is refused at the
    cost of reading its footer.

    Returns {"rows", "samples", "record_s" (all records), "torsional_record_s",
    "torsional"}; raises InputError at the first cap exceeded, naming the file (and row),
    the count found and the limit. Entries that are missing, unreadable or malformed are
    left to :func:`read_campaign`'s report.
    """
    path = os.fspath(path)
    mpath = os.path.join(path, MANIFEST)
    if not os.path.isfile(mpath):
        raise InputError(f"{MANIFEST}: missing; a campaign folder needs {MANIFEST} with columns {', '.join(MANIFEST_COLUMNS)}")
    man = read_manifest(mpath, limits)
    rep = repeated_files(man)
    if rep:
        rel, rows = next(iter(rep.items()))
        raise InputError(f"{MANIFEST}: the file {rel!r} is listed {len(rows)} times (rows {_rows_text(rows)}); accepted is "
                         "each time series listed once, one row per test point")
    out = {"rows": len(man), "samples": 0, "record_s": 0.0, "torsional_record_s": 0.0, "torsional": 0}
    if "file" not in man.columns:
        return out
    inside = os.path.realpath(path)
    cap = limits.samples_per_file
    for i, row in enumerate(man.to_dict("records")):
        rel = _cell(row.get("file"))
        fpath = os.path.realpath(os.path.join(inside, rel)) if rel else ""
        if not rel or os.path.commonpath([inside, fpath]) != inside or not os.path.isfile(fpath):
            continue  # read_campaign reports it (paths_outside refuses entries outside the folder)
        line = f"{MANIFEST} row {i + 2}"
        shape = file_shape(fpath, rel, max_lines=cap)
        n = shape["rows"]
        if cap is not None and n > cap:
            count = f"more than {cap}" if shape["more"] else str(n)
            raise InputError(f"{rel} ({line}): {count} samples; accepted are at most {cap} samples per "
                             "file here (import or diagnose longer records on the command line)")
        if limits.columns is not None and len(shape["columns"]) > limits.columns:
            raise InputError(f"{rel} ({line}): {len(shape['columns'])} columns; accepted are at most {limits.columns} "
                             f"(required: {', '.join(SERIES_COLUMNS)})")
        if limits.bytes_per_sample is not None and n and shape["bytes"] > limits.bytes_per_sample * n + 2**16:
            raise InputError(f"{rel} ({line}): {shape['bytes'] / n:.0f} bytes per sample; accepted are at most "
                             f"{limits.bytes_per_sample} (a row of numbers)")
        out["samples"] += n
        if limits.total_samples is not None and out["samples"] > limits.total_samples:
            raise InputError(f"{rel} ({line}): the campaign's files hold more than {limits.total_samples} samples in all "
                             f"({out['samples']} up to this row); accepted are at most {limits.total_samples} here "
                             "(diagnose larger campaigns with python -m dampersim diagnose CAMPAIGN)")
        fs = _num(row.get("sample_rate_hz"))
        if fs is None or fs <= 0:
            continue  # read_campaign reports the rate; the sample caps bound this file
        seconds = max(n - 1, 0) / fs
        if limits.record_s is not None and seconds > limits.record_s:
            raise InputError(f"{rel} ({line}): a record of {seconds:.4g} s ({n} samples at {fs:g} Hz); accepted are records "
                             f"of at most {limits.record_s:g} s here")
        out["record_s"] += seconds
        if _cell(row.get("kind")).lower() == "torsional":
            out["torsional_record_s"] += seconds
            out["torsional"] += 1
        if limits.total_record_s is not None and out["record_s"] > limits.total_record_s:
            raise InputError(f"{rel} ({line}): the campaign's records last more than {limits.total_record_s:g} s in all "
                             f"({out['record_s']:.4g} s up to this row), above what this server diagnoses; accepted are "
                             f"at most {limits.total_record_s:g} s of records here (diagnose larger campaigns with "
                             "python -m dampersim diagnose CAMPAIGN)")
    return out


def _read_table(path, columns=None):
    """A time series as a DataFrame; only ``columns`` (those present) when given."""
    import pandas as pd

    if path.lower().endswith(".parquet"):
        if columns is not None:
            import pyarrow.parquet as pq

            have = set(pq.ParquetFile(path, memory_map=False).schema_arrow.names)
            return pd.read_parquet(path, columns=[c for c in columns if c in have])
        return pd.read_parquet(path)
    if path.lower().endswith(".csv"):
        if columns is not None:
            wanted = set(columns)
            return pd.read_csv(path, usecols=lambda c: c in wanted)
        return pd.read_csv(path)
    raise InputError(f"{path}: accepted file types are .csv and .parquet")


#: Largest campaign.json read [bytes]; a larger one is ignored like a malformed one.
MAX_CAMPAIGN_JSON_BYTES = 256 * 2**10


def read_campaign_json(path) -> dict:
    """campaign.json of the campaign folder ``path`` as a dict ({} when missing, larger than
    :data:`MAX_CAMPAIGN_JSON_BYTES` or malformed: it is optional)."""
    try:
        with open(os.path.join(os.fspath(path), "campaign.json"), "rb") as fh:
            data = fh.read(MAX_CAMPAIGN_JSON_BYTES + 1)
        if len(data) > MAX_CAMPAIGN_JSON_BYTES:
            return {}
        meta = json.loads(data.decode("utf-8"))
    except (OSError, ValueError, RecursionError):
        return {}
    return meta if isinstance(meta, dict) else {}


def _num(value):
    try:
        x = float(value)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def read_campaign(path, strict: bool = False, limits: CampaignLimits | None = None) -> Campaign:
    """Read and validate the campaign in folder ``path``.

    Returns a :class:`Campaign` with the valid points and every problem found. A missing
    or unreadable manifest raises :class:`InputError`; so does ``strict`` when any problem
    was found. With ``limits``, :func:`scan_campaign` checks them first from metadata and
    its InputError stops the reading before any time series is loaded. A file listed in
    more than one row is read once, for its first row; the other rows are reported. Nothing
    in the folder is written.
    """
    path = os.fspath(path)
    mpath = os.path.join(path, MANIFEST)
    if not os.path.isdir(path):
        raise InputError(f"campaign {path!r}: accepted is a folder holding {MANIFEST}")
    if not os.path.isfile(mpath):
        raise InputError(f"{mpath}: missing; a campaign folder needs {MANIFEST} with columns {', '.join(MANIFEST_COLUMNS)}")
    if limits is not None:
        scan_campaign(path, limits)
    name = os.path.basename(os.path.abspath(path))
    description = ""
    meta = read_campaign_json(path)
    name = str(meta.get("name", name))[:200]
    description = str(meta.get("description", ""))[:2000]
    man = read_manifest(mpath, limits)
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
    first_row = {}  # normalised file entry -> the first manifest row listing it
    for i, row in enumerate(man[list(MANIFEST_COLUMNS)].to_dict("records")):
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
        rel = _cell(row["file"])
        fpath = os.path.join(path, rel)
        key = os.path.normpath(rel.replace("\\", "/")) if rel else ""
        if key and key in first_row:
            bad.append(Problem(line, "file", f"{rel!r} is already listed in row {first_row[key]}; accepted is each time "
                                             "series listed once (this row is ignored)", pid))
        elif not rel or not os.path.isfile(fpath):
            bad.append(Problem(rel or line, "file", "file listed in the manifest does not exist", pid))
        if key:
            first_row.setdefault(key, i + 2)
        if bad:
            problems += bad
            continue
        pt, probs = _read_point(fpath, rel, pid, kind, rpm, tq, fs)
        problems += probs
        if pt is not None:
            points.append(pt)
    listed = {os.path.normpath(_cell(f).replace("\\", "/")) for f in man["file"] if _cell(f)}
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
        man = read_manifest(os.path.join(path, MANIFEST))
    except InputError:  # reported by read_campaign
        return []
    if "file" not in man.columns:
        return []
    out = []
    for i, value in enumerate(man["file"]):
        rel = _cell(value)
        if not rel:
            continue
        target = os.path.realpath(os.path.join(inside, rel))
        if os.path.isabs(rel) or os.path.commonpath([inside, target]) != inside:
            out.append((i + 2, rel))
    return out


def _read_point(fpath, rel, pid, kind, rpm, tq, fs):
    probs = []
    try:
        df = _read_table(fpath, SERIES_COLUMNS + ("windup_deg", "input_flange_deg", "output_flange_deg"))
    except Exception as exc:  # noqa: BLE001
        return None, [Problem(rel, "", f"unreadable ({_short(exc)})", pid)]
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
        try:  # the orders are tracked on this channel (dampersim.discrepancy.tracking)
            check_speed(arrays["input_speed_rpm"] * (math.pi / 30.0), "input_speed_rpm")
        except InputError as exc:
            probs.append(Problem(rel, "input_speed_rpm", str(exc), pid))
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


def check_point(path, row) -> tuple:
    """Read back and check the point of manifest ``row`` in campaign folder ``path`` as
    :func:`read_campaign` does: (MeasuredPoint or None, [Problem])."""
    rel = str(row["file"])
    return _read_point(os.path.join(path, rel), rel, str(row["id"]), row["kind"], float(row["speed_rpm"]),
                       float(row["mean_torque_nm"]), float(row["sample_rate_hz"]))


__all__ = ["MANIFEST", "MANIFEST_COLUMNS", "SERIES_COLUMNS", "KINDS", "Problem", "MeasuredPoint", "Campaign",
           "CampaignLimits", "read_manifest", "read_campaign_json", "repeated_files", "file_shape", "scan_campaign",
           "read_campaign", "paths_outside", "check_point"]
