"""The data behind importing a rig recording on the Discrepancy page: stage an uploaded
recording with a preview of its import, then create the campaign from the reviewed cuts.

Two steps, as on the command line (``python -m dampersim import``), but with the review in
between done in the page:

1. :func:`stage_recording` decodes the browser upload, keeps the bytes in the cache under
   ``private_dir("recording-uploads")/<id>/<file name>`` (the id: the first 16 hex digits
   of the SHA-256 of the bytes, so the same file lands in the same folder; the file name
   reduced to a safe base name) and runs :func:`dampersim.rigdata.importer.import_campaign`
   once into a scratch folder to report the channel mapping and the cuts it proposes
   (kept as ``preview.json`` beside the file; the scratch campaign is removed).
2. :func:`confirm_import` writes the reviewed cut rows as a cuts table and imports the
   staged file again with them, into the folder of campaign uploads that the page lists
   (:func:`dampersim.views.discrepancy.uploads_dir`), so the new campaign is selected like
   an uploaded zip (dropdown value ``upload:<id>``).

Uploads are limited to :data:`MAX_RECORDING_BYTES` (the page's limit for campaign zips:
the server refuses larger requests); larger recordings are imported on the command line.
A refused upload leaves nothing behind. Messages never show the server's folders.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import os
import re
import shutil
import tempfile
import time
from pathlib import Path

from dampersim.discrepancy.campaign import KINDS
from dampersim.discrepancy import upload as campaign_uploads
from dampersim.discrepancy.upload import MAX_CAMPAIGN_ZIP_BYTES, UPLOAD_ID
from dampersim.errors import InputError
from dampersim.fileio import write_text_atomic
from dampersim.locations import private_dir
from dampersim.rigdata import importer
from dampersim.rigdata.importer import import_campaign
from dampersim.uploads import decode_upload
from dampersim.views.discrepancy import UPLOAD_PREFIX, upload_folder, upload_label, uploads_dir
from dampersim.views.notices import notice

#: Sub-directory of the cache with the staged recordings.
STAGING_SUBDIR = "recording-uploads"
#: Largest recording accepted from the browser [bytes]: the limit of the page's campaign
#: zips (the server refuses requests above 16 MB and the browser sends the file
#: base64-encoded, 4/3 of its size).
MAX_RECORDING_BYTES = MAX_CAMPAIGN_ZIP_BYTES
#: Staged recordings older than this [s] are removed when the next one is staged.
STAGED_MAX_AGE_S = 24 * 3600.0
#: Most cut rows one import accepts.
MAX_CUTS = 500
#: The command line for recordings above the upload limit.
IMPORT_COMMAND = "python -m dampersim import FILE --out CAMPAIGN"
RECORDING_FORMATS = ("ASAM MDF 4.x (.mf4), NI TDMS (.tdms), MATLAB MAT-file v5/v7 or v7.3 (.mat) or delimited text "
                     "(.csv) with a header row and a time column")
RECORDING_ACCEPTED = (f"one rig recording of up to {MAX_RECORDING_BYTES // 2**20} MB: {RECORDING_FORMATS}; larger files are "
                      f"imported on the server's command line with {IMPORT_COMMAND}")
SIZE_ACCEPTED = (f"a recording of up to {MAX_RECORDING_BYTES // 2**20} MB here; import a larger one on the server's command "
                 f"line with {IMPORT_COMMAND} and diagnose it with python -m dampersim diagnose CAMPAIGN (or upload the "
                 f"campaign folder here as a zip of up to {MAX_CAMPAIGN_ZIP_BYTES // 2**20} MB)")
#: Columns of a preview's cut rows, in table order.
CUT_FIELDS = ("id", "kind", "speed_rpm", "mean_torque_nm", "start_s", "end_s")
_STAGED_META = "staged.json"
_PREVIEW = "preview.json"


# --------------------------------------------------------------------------- staging
def staging_dir() -> Path:
    """Folder of the staged recordings of this server: a private folder of its cache
    (created 0700, refused when another user owns it or others may write to it)."""
    return private_dir(STAGING_SUBDIR)


def safe_file_name(filename) -> str:
    """A base name safe to store: the last path part of ``filename`` with every character
    other than letters, digits, ``.``, ``_`` and ``-`` replaced, no leading dots, at most 100
    characters ("recording" when nothing is left)."""
    base = re.split(r"[\\/]", str(filename or ""))[-1]
    base = re.sub(r"[^A-Za-z0-9._-]", "_", base).lstrip(".")
    if len(base) > 100:
        stem, dot, ext = base.rpartition(".")
        base = (stem[: 100 - len(ext) - 1] + dot + ext) if dot and len(ext) <= 10 else base[:100]
    return base if base.strip("_") else "recording"


def _clean(text, folders) -> str:
    """``text`` without the server's folders (``folders``: paths, innermost first)."""
    text = str(text)
    for f in folders:
        f = str(f)
        text = text.replace(f + os.sep, "").replace(f, "the upload")
    return text


def prune_staged(max_age_s: float = STAGED_MAX_AGE_S) -> None:
    """Remove staged recordings (and scratch folders) older than ``max_age_s`` seconds."""
    root = staging_dir()
    try:
        entries = list(root.iterdir())
    except OSError:
        return
    limit = time.time() - max_age_s
    for p in entries:
        try:
            if p.is_dir() and (UPLOAD_ID.match(p.name) or p.name.startswith(".")) and p.stat().st_mtime < limit:
                shutil.rmtree(p, ignore_errors=True)
        except OSError:
            continue


def _staged(upload_id) -> tuple:
    """(folder, metadata) of a staged recording; InputError for a refused or unknown id."""
    if not isinstance(upload_id, str) or not UPLOAD_ID.match(upload_id):
        raise InputError(f"recording upload {upload_id!r} is not an upload id: accepted is the 16 hex digits the page "
                         "received when the recording was uploaded")
    folder = staging_dir() / upload_id
    try:
        meta = json.loads((folder / _STAGED_META).read_text(encoding="utf-8"))
        name = meta["file"]
    except (OSError, ValueError, KeyError, TypeError):
        raise InputError(f"recording upload {upload_id!r} is not on this server (staged recordings live in the cache, "
                         "which may have been cleared): upload the recording again") from None
    if not isinstance(name, str) or safe_file_name(name) != name or not (folder / name).is_file():
        raise InputError(f"recording upload {upload_id!r} is incomplete on this server: upload the recording again")
    return folder, meta


def _points_text(points) -> str:
    """"5 test points (4 torsional, 1 ramp)"."""
    n_t = sum(p["kind"] == "torsional" for p in points)
    n_r = len(points) - n_t
    return (f"{len(points)} test point{'s' if len(points) != 1 else ''} ({n_t} torsional, {n_r} "
            f"ramp{'s' if n_r != 1 else ''})")


def _preview_rows(report) -> list:
    return [{k: row[k] for k in CUT_FIELDS} for row in report.points]


def stage_recording(contents, filename) -> dict:
    """A recording from a browser upload (``data:...;base64,...``) -> its import preview.

    Returns {"id" (upload id, 16 hex), "file" (the stored name), "report" (lines: formats,
    channel mapping, the cuts found and rejected), "cuts" (rows: id, kind, speed_rpm,
    mean_torque_nm, start_s, end_s) and "dropped" (cuts the import could not use, with the
    reason)}. Raises InputError naming the file and what is accepted: no content, not
    base64, empty, above :data:`MAX_RECORDING_BYTES` (pointing to the command line), or
    the importer's message (unreadable file, a required channel missing, an ambiguous
    mapping). Nothing is kept of a refused upload.
    """
    label = str(filename or "uploaded file")
    data = decode_upload(contents, label, RECORDING_ACCEPTED, MAX_RECORDING_BYTES,
                         lambda n: f"{n / 2**20:.1f} MB",
                         size_accepted=SIZE_ACCEPTED)
    if not data:
        raise InputError(f"{label} is empty; accepted is {RECORDING_ACCEPTED}")
    digest = hashlib.sha256(data).hexdigest()
    upload_id = digest[:16]
    root = staging_dir()
    try:
        preview = dict(json.loads((root / upload_id / _PREVIEW).read_text(encoding="utf-8")), id=upload_id)
        os.utime(root / upload_id)  # in use again: not pruned for another STAGED_MAX_AGE_S
        return preview
    except (OSError, ValueError, TypeError):
        pass  # not staged before (or damaged): stage it now
    prune_staged()
    try:
        os.makedirs(root, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cache directory {str(root)!r} cannot be used ({exc.strerror or exc}); "
                         "set DAMPERSIM_CACHE_DIR to a writable folder") from None
    name = safe_file_name(filename)
    tmp = Path(tempfile.mkdtemp(prefix=f".{upload_id}-", dir=root))
    try:
        (tmp / name).write_bytes(data)
        scratch = tmp / ".preview"
        try:
            report = import_campaign([tmp / name], scratch)
        except InputError as exc:
            text = _clean(exc, [scratch, tmp])
            if "write a map file" in text:
                text += ("; accepted on this page are recordings whose channels are recognised by name and unit; "
                         "with a map file, import on the server's command line: "
                         "python -m dampersim import FILE --map MAP.toml --out CAMPAIGN")
            raise InputError(label + text[len(name):] if text.startswith(name) else f"{label}: {text}") from None
        finally:
            shutil.rmtree(scratch, ignore_errors=True)
        lines = [_clean(line, [scratch, tmp]) for line in report.lines]
        if lines and lines[-1].startswith("wrote "):
            lines[-1] = f"proposed: {_points_text(report.points)}; review the cuts, then create the campaign"
        preview = {"id": upload_id, "file": name, "report": lines, "cuts": _preview_rows(report),
                   "dropped": [{**d} for d in report.dropped]}
        shown = re.split(r"[\\/]", label)[-1][:200] or name  # the user's file name, for labels only
        meta = {"file": name, "filename": shown, "sha256": digest, "bytes": len(data)}
        write_text_atomic(tmp / _STAGED_META, json.dumps(meta))
        write_text_atomic(tmp / _PREVIEW, json.dumps(preview))
        dest = root / upload_id
        try:
            os.replace(tmp, dest)
        except OSError:
            try:
                _staged(upload_id)  # staged at the same time by another request: use that one
            except InputError:  # a damaged earlier staging: replace it
                shutil.rmtree(dest, ignore_errors=True)
                os.replace(tmp, dest)
        return preview
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


# --------------------------------------------------------------------------- confirm
def check_cut_rows(rows) -> list:
    """Reviewed cut rows of the page's table -> ``[(id, kind, start_s, end_s)]``
    (:func:`dampersim.rigdata.importer.check_cut_rows`, rows named as the table shows them:
    ``cut row N (id)``), at most :data:`MAX_CUTS` of them."""
    if isinstance(rows, (list, tuple)) and len(rows) > MAX_CUTS:
        raise InputError(f"{len(rows)} cut rows; accepted are at most {MAX_CUTS}")
    return [(pid, kind, t0, t1) for kind, t0, t1, pid in importer.check_cut_rows(rows, lambda i: f"cut row {i}")]


def cuts_csv(cuts, source_file: str) -> str:
    """The cuts table the importer reads (:func:`dampersim.rigdata.importer.read_cuts`):
    columns id, kind, source_file, start_s, end_s; times written exactly."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["id", "kind", "source_file", "start_s", "end_s"])
    for pid, kind, t0, t1 in cuts:
        w.writerow([pid, kind, source_file, repr(float(t0)), repr(float(t1))])
    return buf.getvalue()


def confirm_import(upload_id, rows) -> dict:
    """Create the campaign of a staged recording (:func:`stage_recording`) from the
    reviewed cut rows (the preview's rows, edited: rows deleted, kind, start_s and end_s
    changed; the source file is always the staged one).

    The campaign lands in :func:`dampersim.views.discrepancy.uploads_dir` under an id
    that hashes the recording and the cuts (the same cuts again select the campaign made
    before). Returns {"value" (the campaign dropdown value, ``upload:<id>``), "upload"
    (the id), "label" (its dropdown label), "points" (rows written), "report" (lines),
    "notices"}. Raises InputError for a refused or unknown upload id, an invalid row
    (naming the row and field, see :func:`check_cut_rows`) and the importer's refusals
    (e.g. no cut gave a test point); nothing is listed then.
    """
    folder, meta = _staged(upload_id)
    cuts = check_cut_rows(rows)
    name = meta["file"]
    text = cuts_csv(cuts, name)
    cid = hashlib.sha256(f"{upload_id}\n{text}".encode()).hexdigest()[:16]
    value = UPLOAD_PREFIX + cid
    root = uploads_dir()
    if upload_folder(cid) is not None:
        return {"value": value, "upload": cid, "label": upload_label(cid), "points": [], "report": [],
                "notices": [notice(f"{name} with these cuts was imported before: that campaign is selected.", "info")]}
    stem = Path(name).stem or name
    title = f"{stem} #{cid[:6]}"
    os.makedirs(root, exist_ok=True)
    target = root / cid
    fd, cuts_path = tempfile.mkstemp(prefix=".cuts-", suffix=".csv", dir=folder)
    os.close(fd)
    meta_path = root / f"{cid}.json"
    try:
        Path(cuts_path).write_text(text, encoding="utf-8")
        write_text_atomic(meta_path, json.dumps({"filename": meta.get("filename") or name, "name": title,
                                                 "source": "rig recording"}))
        try:
            report = import_campaign([folder / name], target, cuts_path=cuts_path, name=title,
                                     description=f"Imported from the rig recording {name} with {len(cuts)} reviewed cuts.")
        except InputError as exc:
            if upload_folder(cid) is not None:  # created at the same time by another request
                return {"value": value, "upload": cid, "label": upload_label(cid), "points": [], "report": [],
                        "notices": [notice(f"{name} with these cuts was imported just now: that campaign is selected.",
                                           "info")]}
            meta_path.unlink(missing_ok=True)
            text = _clean(exc, [target, folder, root])
            dropped = [line.strip() for line in text.splitlines() if line.strip().startswith("dropped ")]
            if text.startswith("no test point could be cut") and dropped:
                text = "no test point could be cut with these cuts: " + "; ".join(dropped)
            raise InputError(text) from None
        except BaseException:
            meta_path.unlink(missing_ok=True)
            raise
        size = campaign_uploads.folder_bytes(target)
        try:  # the new campaign counts against the uploads quota like an uploaded zip
            with campaign_uploads.quota_lock(root):
                campaign_uploads.make_room(root, size, keep=cid)
        except InputError:
            campaign_uploads.remove_upload(root, cid)
            raise
        write_text_atomic(meta_path, json.dumps({"filename": meta.get("filename") or name, "name": title,
                                                 "source": "rig recording", "bytes": size}))
    finally:
        Path(cuts_path).unlink(missing_ok=True)
    lines = [_clean(line, [target, folder, root]) for line in report.lines]
    if lines and lines[-1].startswith("wrote "):
        lines[-1] = f"wrote {_points_text(report.points)} to the campaign {title}"
    notes = [notice(f"Created the campaign {title} from {name}: {_points_text(report.points)}. It is selected in the "
                    "campaign list; its validation report is shown on the right.", "success")]
    for d in report.dropped:
        pid = next((c[0] for c in cuts if abs(c[2] - d["start_s"]) < 1e-3 and abs(c[3] - d["end_s"]) < 1e-3), None)
        what = f"Cut {pid} (" if pid else "The cut ("
        notes.append(notice(f"{what}{d['kind']} {d['start_s']:.2f}-{d['end_s']:.2f} s) was left out: "
                            f"{_clean(d['reason'], [folder])}.", "warning"))
    return {"value": value, "upload": cid, "label": upload_label(cid), "points": report.points, "report": lines,
            "notices": notes}


__all__ = [
    "STAGING_SUBDIR",
    "MAX_RECORDING_BYTES",
    "MAX_CUTS",
    "IMPORT_COMMAND",
    "RECORDING_ACCEPTED",
    "CUT_FIELDS",
    "KINDS",
    "staging_dir",
    "safe_file_name",
    "prune_staged",
    "stage_recording",
    "check_cut_rows",
    "cuts_csv",
    "confirm_import",
]
