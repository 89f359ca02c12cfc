"""Import rig recordings into a campaign folder: read, map channels, cut into test points, write.

One call of :func:`import_campaign` turns one or more recordings (MDF4, TDMS, MAT, CSV;
see :mod:`dampersim.rigdata.readers`) into the campaign format that the discrepancy
workflow reads (:mod:`dampersim.discrepancy.campaign`):

1. each file is opened by content and its channels are mapped onto the campaign's columns
   (:mod:`dampersim.rigdata.mapping`: a map file, or matching by name and unit, reported);
2. speed and input torque are read at a reduced rate (:data:`SEGMENT_RATE_HZ`, low-passed
   first) and the recording is cut into steady plateaus (torsional points) and torque
   ramps (:mod:`dampersim.rigdata.segment`), or into the cuts of an edited manifest;
3. every point's window is read channel by channel (only that window: a long MDF4 file is
   never loaded whole), converted to the campaign's units and brought onto one uniform
   time base (:mod:`dampersim.rigdata.resample`);
4. the folder is written next to the target under a temporary name and renamed into place
   only when complete, so an interrupted import never leaves something that looks like a
   valid campaign. The manifest lists the points in recording order, with the source file
   and the cut (``source_file``, ``start_s``, ``end_s``) as extra columns; ``campaign.json``
   records the source files with their SHA-256 and format, and the mapping used.

A problem with one point (a NaN burst, a window too short, a ramp without windup) drops
that point with a line in the report; a problem with a file (unreadable, a required
channel missing, an ambiguous mapping) stops the import with an :class:`InputError`.
"""

from __future__ import annotations

import hashlib
import math
import os
import re
import shutil
import tempfile
from dataclasses import dataclass, field

import numpy as np

from dampersim.discrepancy.campaign import (
    MANIFEST,
    MIN_RAMP_S,
    MIN_REVOLUTIONS,
    MIN_TORSIONAL_S,
    KINDS,
    MeasuredPoint,
    check_point,
)
from dampersim.discrepancy.campaign_write import write_manifest, write_point
from dampersim.errors import InputError
from dampersim.rigdata import mapping, resample, segment
from dampersim.rigdata.readers import open_recording, sniff_format
from dampersim.signal import sample_rate_from_time
from dampersim.units import parse_number

#: Rate [Hz] of the speed and torque traces the recording is cut on: far above the
#: plateau and ramp dynamics (< 5 Hz), and its anti-alias cut-off (0.4 x 500 = 200 Hz)
#: keeps order 2, by which a plateau's excitation is recognised, up to 6000 rpm; a 500 MB
#: recording's cut traces stay a few MB.
SEGMENT_RATE_HZ = 500.0
#: Highest engine order the campaign must resolve ([thesis] §3.4: orders 1-8) and the
#: margin above Nyquist we ask of a point's sample rate.
MAX_ORDER = 8
NYQUIST_MARGIN = 2.2
#: A point id as the cuts may give it: it becomes the name of the point's file.
_POINT_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")
#: Columns the import adds to the manifest so that the cuts can be reviewed and edited.
CUT_COLUMNS = ("source_file", "start_s", "end_s")


@dataclass
class ImportReport:
    """What an import did: points written, points dropped, and every decision, in words."""

    campaign: str
    points: list = field(default_factory=list)  # manifest rows written (dicts)
    dropped: list = field(default_factory=list)  # {"source_file", "start_s", "end_s", "reason"}
    lines: list = field(default_factory=list)  # the report, one decision per line

    def to_dict(self) -> dict:
        return {"campaign": self.campaign, "points": self.points, "dropped": self.dropped, "report": self.lines}

    def text(self) -> str:
        return "\n".join(self.lines)


# --------------------------------------------------------------------------- sources
def source_files(sources) -> list:
    """The files to import, in the given order; a folder stands for the files directly in it
    (sorted by name, hidden files skipped). A missing path raises InputError."""
    files = []
    for s in sources:
        s = os.fspath(s)
        if os.path.isdir(s):
            inner = sorted(f for f in os.listdir(s) if not f.startswith(".") and os.path.isfile(os.path.join(s, f)))
            if not inner:
                raise InputError(f"{s!r}: the folder holds no files; accepted is a folder of recordings or the files themselves")
            files += [os.path.join(s, f) for f in inner]
        elif os.path.isfile(s):
            files.append(s)
        else:
            raise InputError(f"{s!r}: no such file or folder; accepted is a recording file or a folder of them")
    return [os.path.abspath(f) for f in files]


def sha256_of(path) -> str:
    """SHA-256 (hex) of a file, read in 1 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(2**20), b""):
            h.update(chunk)
    return h.hexdigest()


def check_target(out) -> str:
    """Absolute path of the campaign to write: it must not exist yet, or be an empty folder."""
    out = os.path.abspath(os.fspath(out))
    if os.path.exists(out) and (not os.path.isdir(out) or os.listdir(out)):
        raise InputError(f"--out {out!r}: exists and is not an empty folder; accepted is a new or empty folder")
    return out


# --------------------------------------------------------------------------- cuts
def check_cut_rows(rows, name_row) -> list:
    """Cut rows (dicts with id, kind, start_s, end_s [s]; other keys ignored) ->
    ``[(kind, start_s, end_s, id)]``.

    ``name_row(i)`` names row ``i`` (1-based) in messages, e.g. "--cuts row 3". Raises
    InputError naming the row, its id and the field: an id that cannot name a point's file,
    a repeated id, a kind other than torsional or ramp, a start or end that is not a
    number, or not 0 <= start_s < end_s; and for no rows at all.
    """
    if not isinstance(rows, (list, tuple)) or not rows:
        raise InputError("no cuts left to import; accepted is at least one row with id, kind, start_s and end_s")
    out, seen = [], set()
    for i, row in enumerate(rows, start=1):
        if not isinstance(row, dict):
            raise InputError(f"{name_row(i)}: accepted is a row with id, kind, start_s and end_s")
        pid = str(row.get("id", "")).strip()
        where = f"{name_row(i)} ({pid})" if pid else name_row(i)
        if not _POINT_ID.match(pid):
            raise InputError(f"{where} [id]: {row.get('id')!r}; accepted is a point id of letters, digits, '.', '_' and "
                             "'-' (up to 64 characters, starting with a letter or digit; it names the point's file)")
        if pid in seen:
            raise InputError(f"{where} [id]: {pid!r} is given twice; accepted is one row per point id")
        seen.add(pid)
        kind = str(row.get("kind", "")).strip().lower()
        if kind not in KINDS:
            raise InputError(f"{where} [kind]: {row.get('kind')!r}; accepted is torsional or ramp")
        times = {}
        for name in ("start_s", "end_s"):
            raw = row.get(name)
            try:
                times[name] = parse_number("" if raw is None else raw)
            except ValueError as exc:
                shown = "the value" if raw is None or str(raw).strip() == "" else repr(raw)
                raise InputError(f"{where} [{name}]: {shown} {exc}; accepted are seconds from the start of the "
                                 "recording with 0 <= start_s < end_s") from None
        t0, t1 = times["start_s"], times["end_s"]
        if t0 < 0:
            raise InputError(f"{where} [start_s]: {t0!r} is negative; accepted is 0 <= start_s < end_s")
        if t1 <= t0:
            raise InputError(f"{where} [end_s]: {t1!r} is not after start_s = {t0!r}; accepted is 0 <= start_s < end_s")
        out.append((kind, t0, t1, pid))
    return out


def read_cuts(path) -> dict:
    """Cuts from an edited manifest: {source file name: [(kind, start_s, end_s, id)]}.

    The manifest is the one an import wrote (columns ``id``, ``kind``, ``source_file``,
    ``start_s``, ``end_s``); rows may be deleted, their kind, start and end edited. Every
    row is checked by :func:`check_cut_rows`.
    """
    import pandas as pd

    try:
        man = pd.read_csv(path, dtype=str, keep_default_na=False)
    except Exception as exc:  # noqa: BLE001 - any parse failure is bad input
        raise InputError(f"--cuts {os.fspath(path)!r}: not a readable CSV table ({exc})") from None
    need = ("id", "kind") + CUT_COLUMNS
    missing = [c for c in need if c not in man.columns]
    if missing:
        raise InputError(f"--cuts {os.fspath(path)!r}: missing column(s) {', '.join(missing)}; accepted is the "
                         f"manifest an import wrote (columns {', '.join(need)})")
    rows = man.to_dict("records")
    cuts: dict = {}
    for row, cut in zip(rows, check_cut_rows(rows, lambda i: f"--cuts row {i + 1}")):
        cuts.setdefault(str(row["source_file"]).strip(), []).append(cut)
    return cuts


# --------------------------------------------------------------------------- one file
def _read_mapped(rec, spec, target, t0=None, t1=None):
    t, x = rec.read(spec.name) if t0 is None else rec.read_window(spec.name, t0, t1)
    return np.asarray(t, dtype=float), mapping.convert(x, spec.unit, target, spec.gain, spec.offset)


#: The segmentation traces are read in pieces of this length [s] of the recording, each
#: with SEGMENT_OVERLAP_S [s] more read either side: at 20 kHz a piece is 1.2 M samples
#: (about 10 MB a channel), however long the recording.
SEGMENT_PIECE_S = 60.0
#: Overlap [s] read either side of a piece and dropped after the low pass: 200 periods of
#: its 200 Hz cut-off, where its response to the cut edge (below 1e-4 after 12 periods,
#: resample.GUARD_PERIODS) has long vanished; the pieces join as the whole trace would.
SEGMENT_OVERLAP_S = 1.0


def _on_grid(target, t, x, t_grid, rate_hz=None):
    """Values ``x`` [any unit] at times ``t`` [s] brought onto ``t_grid`` [s] at
    SEGMENT_RATE_HZ as resample.common_time_base does: low-passed first when faster.
    ``rate_hz``: the channel's rate [Hz] as the reader found it over the whole recording,
    used when the piece agrees with it, so that every piece is filtered alike."""
    try:
        fs = sample_rate_from_time(t)
    except InputError as exc:
        raise InputError(f"{target}: {exc}") from None
    if rate_hz and abs(fs / rate_hz - 1.0) <= 1e-9:
        fs = float(rate_hz)
    if fs > SEGMENT_RATE_HZ * (1 + resample.SAME_RATE_TOLERANCE):
        x = resample.lowpass(x, fs, resample.CUTOFF_FRACTION * SEGMENT_RATE_HZ)
    return resample.cubic_at(x, float(t[0]), fs, t_grid)


def _segment_traces(rec, specs):
    """Speed [rpm] and input torque [N m] on one time base at about SEGMENT_RATE_HZ.

    The two channels are read SEGMENT_PIECE_S [s] at a time (plus SEGMENT_OVERLAP_S either
    side), each piece low-passed and interpolated onto its part of the common time base,
    so that the memory needed stays that of one piece, not of whole channels at their full
    rate (a 500 MB recording's torque channel alone is about 250 MB as float64 time and
    values, several times that while filtered). A recording that fits in one piece is
    resampled whole, by resample.common_time_base. The time base is the one
    common_time_base would build: SEGMENT_RATE_HZ from the later of the two first samples
    to the earlier of the two last ones.
    """
    keys = ("input_speed_rpm", "input_torque_nm")
    samples = {c.name: c.samples for c in rec.channels}
    rates = {c.name: c.rate_hz for c in rec.channels}
    rate, piece, margin = SEGMENT_RATE_HZ, SEGMENT_PIECE_S, SEGMENT_OVERLAP_S
    seen = dict.fromkeys(keys, 0)
    first, last = dict.fromkeys(keys), dict.fromkeys(keys)
    times, cols = [], {k: [] for k in keys}
    start = None
    k = 0
    while True:
        a, b = k * piece, (k + 1) * piece
        series = {key: _read_mapped(rec, specs[key], key, a - margin, b + margin) for key in keys}
        done = []
        for key, (t, _x) in series.items():
            core = t[(t >= a) & (t < b)]
            if core.size:
                first[key] = core[0] if first[key] is None else first[key]
                last[key] = core[-1]
                seen[key] += core.size
            if seen[key] >= samples[specs[key].name]:
                done.append(key)
            elif first[key] is not None and t.size == 0:
                raise InputError(f"{key}: channel {specs[key].name!r} has no samples from {a - margin:.6g} to "
                                 f"{b + margin:.6g} s; accepted is a uniform time base without gaps")
        if k == 0 and len(done) == len(keys):  # every sample read: the whole trace at once
            t, out, _ = resample.common_time_base(series, rate_hz=rate)
            return t, out["input_speed_rpm"], out["input_torque_nm"]
        if start is None and all(first[key] is not None for key in keys):
            start = max(first.values())
        if done and (start is None or not min(last[key] for key in done) > start):
            spans = ", ".join(f"{key} {first[key]:.6g}-{last[key]:.6g} s" for key in keys if last[key] is not None)
            raise InputError(f"the channels do not overlap in time ({spans}); accepted are channels recorded together")
        if start is not None:
            # this piece's samples of the common base: those from a [s] up to b [s]
            lo, hi = max(0, math.ceil((a - start) * rate)), max(0, math.ceil((b - start) * rate))
            if done:
                end = min(last[key] for key in done)
                hi = min(hi, int(math.floor((end - start) * rate * (1 + 1e-12))) + 1)
            if hi > lo:
                t_grid = start + np.arange(lo, hi) / rate
                times.append(t_grid)
                for key, (t, x) in series.items():
                    cols[key].append(_on_grid(key, t, x, t_grid, rates[specs[key].name]))
        if done:
            break
        k += 1
    t = np.concatenate(times) if times else np.empty(0)
    if t.size < 2:
        raise InputError(f"the speed and torque channels overlap for {t.size} sample(s) at {rate:g} Hz; accepted is "
                         "an overlap of at least two samples")
    return t, np.concatenate(cols["input_speed_rpm"]), np.concatenate(cols["input_torque_nm"])


def _point(rec, specs, kind, t0, t1, pid, rate_hz):
    """MeasuredPoint of window [t0, t1) [s], or (None, reason)."""
    series = {k: _read_mapped(rec, s, k, t0, t1) for k, s in specs.items()}
    for k, (t, _x) in series.items():
        if t.size < 16:
            return None, f"channel {specs[k].name!r} has {t.size} samples in the window"
    t, cols, note = resample.common_time_base(series, rate_hz=rate_hz)
    bad = [specs[k].name for k, x in cols.items() if not np.all(np.isfinite(x))]
    if bad:
        return None, f"NaN/inf samples in {', '.join(bad)}"
    fs = float(f"{1.0 / float(np.mean(np.diff(t))):.10g}")  # the uniform base's rate, without rounding noise
    rpm = float(np.mean(cols["input_speed_rpm"]))
    torque = float(np.mean(cols["input_torque_nm"]))
    dur = float(t[-1] - t[0])
    windup = None
    if kind == "torsional":
        need = max(MIN_TORSIONAL_S, MIN_REVOLUTIONS * 60.0 / max(rpm, 1e-9))
        if dur < need:
            return None, f"window of {dur:.3g} s is shorter than the order analysis needs ({need:.3g} s at {rpm:.0f} rpm)"
        if fs < NYQUIST_MARGIN * MAX_ORDER * rpm / 60.0:
            return None, f"sample rate {fs:.4g} Hz cannot resolve order {MAX_ORDER} at {rpm:.0f} rpm"
    else:
        if dur < MIN_RAMP_S:
            return None, f"ramp window of {dur:.3g} s is shorter than {MIN_RAMP_S:g} s"
        if "windup_deg" in cols:
            windup = np.radians(cols["windup_deg"])
        elif "input_flange_deg" in cols and "output_flange_deg" in cols:
            windup = np.radians(cols["input_flange_deg"] - cols["output_flange_deg"])
        else:
            return None, "a ramp needs windup_deg or input_flange_deg and output_flange_deg; none is mapped"
    point = MeasuredPoint(
        id=pid, kind=kind, speed_rpm=round(rpm, 3), mean_torque_nm=round(torque, 3), sample_rate_hz=fs,
        time=t - t[0], input_torque=cols["input_torque_nm"], output_torque=cols["output_torque_nm"],
        input_speed_rpm=cols["input_speed_rpm"], output_speed_rpm=cols["output_speed_rpm"], windup=windup,
    )
    return point, note


def _import_file(path, channel_map, cuts, rate_hz, report: ImportReport, store):
    """Cut one recording into points and hand each to ``store(point, cut) -> bool`` (written
    and checked) as soon as it is made, so that one point at a time is held in memory;
    returns the file's source record and the mapping used."""
    name = os.path.basename(path)
    fmt = sniff_format(path)
    with open_recording(path) as rec:
        res = mapping.resolve(rec.channels, channel_map)
        report.lines.append(f"{name}: {fmt}, {len(rec.channels)} channels")
        report.lines += [f"  {line}" for line in res.report]
        specs = dict(res.specs)
        if cuts is None:
            t, speed, torque = _segment_traces(rec, specs)
            found = segment.find_segments(t, speed, torque)
            segments, rejected = found.segments, found.rejected
            del t, speed, torque
            plan = [(s.kind, s.start_s, s.end_s, None) for s in segments]
            for r in rejected:
                report.lines.append(f"  not a test point: {r.kind} {r.start_s:.2f}-{r.end_s:.2f} s ({r.reason})")
            report.lines.append(f"  {len(plan)} test points found on the speed and input torque traces")
        else:
            plan = cuts.get(name, [])
            report.lines.append(f"  {len(plan)} cuts taken from the edited manifest")
        last_note = None
        for kind, t0, t1, pid in plan:
            pid = pid or f"p{len(report.points) + 1:03d}"
            point, note = _point(rec, specs, kind, t0, t1, pid, rate_hz)
            cut = {"source_file": name, "start_s": round(float(t0), 4), "end_s": round(float(t1), 4)}
            if point is None:
                report.dropped.append({**cut, "kind": kind, "reason": note})
                report.lines.append(f"  dropped {kind} {t0:.2f}-{t1:.2f} s: {note}")
                continue
            if store(point, cut):
                last_note = note
        if last_note is not None:
            report.lines.append(f"  resampling (last point): {last_note}")
        mapping_doc = {k: {"name": s.name, "unit": s.unit, "gain": s.gain, "offset": s.offset} for k, s in specs.items()}
    return {"file": name, "sha256": sha256_of(path), "format": fmt}, mapping_doc


# --------------------------------------------------------------------------- campaign
def import_campaign(sources, out, map_path=None, cuts_path=None, rate_hz=None, name="", description="") -> ImportReport:
    """Import recordings ``sources`` (files or folders) into a new campaign folder ``out``.

    map_path: channel map TOML (:func:`dampersim.rigdata.mapping.load_map`), None to match
    by name and unit; cuts_path: an import's manifest with edited cuts, None to find the
    test points automatically; rate_hz: sample rate [Hz] of the written points (None: the
    highest channel rate of each file). Returns the :class:`ImportReport`; raises
    InputError for a file-level problem, leaving nothing behind.
    """
    files = source_files(sources)
    target = check_target(out)
    channel_map = mapping.load_map(map_path) if map_path is not None else None
    cuts = read_cuts(cuts_path) if cuts_path is not None else None
    if cuts is not None:
        unknown = sorted(set(cuts) - {os.path.basename(f) for f in files})
        if unknown:
            raise InputError(f"--cuts names source file(s) {', '.join(unknown)} that are not imported now")
    report = ImportReport(campaign=target)
    parent = os.path.dirname(target)
    os.makedirs(parent, exist_ok=True)
    tmp = tempfile.mkdtemp(prefix=f".{os.path.basename(target)}.partial-", dir=parent)

    def store(point, cut) -> bool:
        """Write ``point`` now, read it back as the campaign reader will, keep its row."""
        row = write_point(tmp, point, columns=cut)
        _, problems = check_point(tmp, row)
        if problems:
            os.remove(os.path.join(tmp, row["file"]))
            reason = "; ".join(q.message for q in problems)
            report.dropped.append({**cut, "kind": point.kind, "reason": reason})
            report.lines.append(f"  dropped {point.kind} {cut['start_s']:.2f}-{cut['end_s']:.2f} s: {reason}")
            return False
        report.points.append(row)
        return True

    try:
        sources_doc, mappings = [], {}
        for path in files:
            src, mapped = _import_file(path, channel_map, cuts, rate_hz, report, store)
            sources_doc.append(src)
            mappings[src["file"]] = mapped
        if not report.points:
            raise InputError("no test point could be cut from the recordings:\n" + report.text())
        meta = {
            "source": {"files": [s["file"] for s in sources_doc], "sha256": [s["sha256"] for s in sources_doc],
                       "format": [s["format"] for s in sources_doc]},
            "mapping": mappings,
        }
        write_manifest(tmp, report.points, name=name or os.path.basename(target), description=description, metadata=meta)
        if os.path.isdir(target):
            os.rmdir(target)  # empty, checked above
        os.replace(tmp, target)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    report.lines.append(f"wrote {len(report.points)} test points to {target} ({MANIFEST} in recording order)")
    return report


__all__ = ["ImportReport", "import_campaign", "source_files", "check_cut_rows", "read_cuts", "check_target", "sha256_of",
           "SEGMENT_RATE_HZ", "CUT_COLUMNS"]
