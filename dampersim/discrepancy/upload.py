"""Unpacking a campaign uploaded from a browser: the zip arrives base64-encoded and is checked
(size, entries, one campaign, nothing outside its folder, and the size of its test points
from their metadata) before anything is kept.

Uploads live in a folder the caller chooses (the dashboard: ``private_dir("uploads")`` of
its cache), one sub-folder per upload named by the first 16 hex digits of the SHA-256 of
the zip, with a small JSON file beside it holding the file and campaign names and the
folder's size.

Limits of one upload (refused before anything is kept, each message naming the file, the
count found and the limit):

- the zip: :data:`MAX_CAMPAIGN_ZIP_BYTES`, at most :data:`MAX_CAMPAIGN_FILES` files and
  :data:`MAX_CAMPAIGN_UNPACKED_BYTES` unpacked (checked against the archive's directory
  and again while unpacking); no absolute paths, "..", links or encrypted entries;
- the campaign, from metadata only (:func:`dampersim.discrepancy.campaign.scan_campaign`
  with :data:`UPLOAD_LIMITS`): manifest rows, each file listed once, samples per file and
  in all (Parquet footer, CSV header and a bounded line count), seconds per record and in
  all (the diagnosis's cost grows with the seconds of record it simulates).

Quota of all uploads (server settings; each also an environment variable read at call
time): at most :data:`MAX_UPLOADS` campaigns (``DAMPERSIM_UPLOADS_MAX``) and
:data:`MAX_UPLOADS_BYTES` on disk (``DAMPERSIM_UPLOADS_MB``, in MB). When a new upload
would exceed either, the least recently used uploads are removed first; an upload in use
(a diagnosis running on it, see :func:`upload_in_use`, or used within the last
:data:`IN_USE_S` seconds) is never removed, and when the quota cannot be met without
removing one the new upload is refused instead. :func:`cleanup_stale_uploads` removes
temporary folders left by interrupted uploads (the server calls it at start-up).
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import re
import shutil
import stat
import tempfile
import time
import zipfile
import zlib
from pathlib import Path, PurePosixPath

from dampersim.discrepancy.campaign import MANIFEST, CampaignLimits, paths_outside, read_campaign_json, scan_campaign
from dampersim.errors import InputError
from dampersim.uploads import decode_upload

#: Largest campaign zip accepted [bytes] (the dashboard's server refuses requests above
#: 16 MB and the browser sends the file base64-encoded, 4/3 of its size).
MAX_CAMPAIGN_ZIP_BYTES = 10 * 2**20
#: Most files, and most bytes once unpacked, of one uploaded campaign (refused before
#: anything is written, so an archive that expands enormously is never unpacked).
MAX_CAMPAIGN_FILES = 2000
MAX_CAMPAIGN_UNPACKED_BYTES = 256 * 2**20

#: Caps of an uploaded campaign, checked from metadata before any time series is loaded
#: (:func:`dampersim.discrepancy.campaign.scan_campaign`). Why these values: a rig
#: campaign of 40 points of 1.25 s at 20 kHz holds 1 million samples and 50 s of record;
#: a hysteresis ramp protocol lasts 30-60 s. 2 million samples of six float64 columns
#: take about 100 MB while the campaign is validated; 600 s of record are some 56 minutes
#: of diagnosis on 2 cores (11.2 core seconds per second of record). Larger campaigns are
#: diagnosed on the command line.
UPLOAD_LIMITS = CampaignLimits(rows=500, samples_per_file=1_000_000, total_samples=2_000_000, record_s=120.0,
                               total_record_s=600.0, bytes_per_sample=1024, columns=64)
#: Quota of all uploaded campaigns: most campaigns kept and most bytes on disk (defaults;
#: the environment variables DAMPERSIM_UPLOADS_MAX and DAMPERSIM_UPLOADS_MB override them).
MAX_UPLOADS = 50
MAX_UPLOADS_BYTES = 2 * 2**30
#: An upload used (selected, validated, diagnosed) within this many seconds is in use and
#: is not evicted to make room for another.
IN_USE_S = 600.0
#: Temporary extraction folders older than this [s] are stale (see :func:`cleanup_stale_uploads`).
STALE_TEMP_S = 3600.0

CAMPAIGN_ACCEPTED = (f"a .zip (up to {MAX_CAMPAIGN_ZIP_BYTES // 2**20} MB) of one campaign folder: manifest.csv with the "
                     "columns id, kind, speed_rpm, mean_torque_nm, file, sample_rate_hz, the time series it lists "
                     "(.parquet or .csv) and optionally campaign.json (see docs/discrepancy.md)")
#: An upload id: 16 hex digits.
UPLOAD_ID = re.compile(r"^[0-9a-f]{16}$")
#: A temporary extraction folder: "." + upload id + "-" + random suffix.
_TEMP = re.compile(r"^\.[0-9a-f]{16}-")
_BUSY = ".busy"


def upload_quota() -> tuple:
    """(most campaigns, most bytes) of the uploads quota: the environment variables
    DAMPERSIM_UPLOADS_MAX and DAMPERSIM_UPLOADS_MB (read now) or the defaults
    :data:`MAX_UPLOADS` and :data:`MAX_UPLOADS_BYTES`; InputError for a value that is not a
    positive number."""
    out = []
    for env, default, scale in (("DAMPERSIM_UPLOADS_MAX", MAX_UPLOADS, 1), ("DAMPERSIM_UPLOADS_MB", MAX_UPLOADS_BYTES, 2**20)):
        raw = os.environ.get(env, "").strip()
        if not raw:
            out.append(default)
            continue
        try:
            val = float(raw)
        except ValueError:
            val = -1.0
        if not (val > 0 and val < 1e12):
            raise InputError(f"{env}={raw!r}: accepted is a positive number (campaigns, or MB of disk)")
        out.append(max(1, int(val * scale)))
    return tuple(out)


def _manifest_dirs(root: Path) -> list:
    """Shallowest folders under ``root`` that hold a manifest.csv."""
    hits = []
    for sub, dirs, files in os.walk(root):
        dirs.sort()
        if MANIFEST in files:
            hits.append(Path(sub))
            dirs[:] = []  # a campaign's own sub-folders are its data, not more campaigns
    if not hits:
        return []
    depth = min(len(h.relative_to(root).parts) for h in hits)
    return [h for h in hits if len(h.relative_to(root).parts) == depth]


def upload_folder(root, upload_id):
    """Campaign folder of an upload unpacked into ``root`` earlier, or None (unknown id or
    a folder that was removed)."""
    if not isinstance(upload_id, str) or not UPLOAD_ID.match(upload_id):
        return None
    folder = Path(root) / upload_id
    if not folder.is_dir():
        return None
    found = _manifest_dirs(folder)
    if len(found) != 1:
        return None
    _touch(Path(root), upload_id)
    return found[0]


def _touch(root: Path, upload_id: str) -> None:
    """Mark an upload as used now (its metadata file's time: the order of eviction)."""
    try:
        os.utime(root / f"{upload_id}.json")
    except OSError:
        pass


def upload_metadata(root, upload_id: str):
    """{"filename", "name"} written beside an upload in ``root``, or None when unknown."""
    try:
        meta = json.loads((Path(root) / f"{upload_id}.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return meta if isinstance(meta, dict) else None


def _zip_members(zf, name: str, accepted: str) -> list:
    """(ZipInfo, relative parts) of the files to unpack; refuses unsafe or huge archives."""
    members, total = [], 0
    for zi in zf.infolist():
        if zi.is_dir():
            continue
        raw = zi.filename.replace("\\", "/")
        parts = PurePosixPath(raw).parts
        if raw.startswith("/") or not parts or ".." in parts or ":" in parts[0]:
            raise InputError(f"{name}: the entry {zi.filename!r} points outside the archive; accepted is {accepted}")
        if parts[0] == "__MACOSX" or parts[-1].startswith("._") or parts[-1] == ".DS_Store":
            continue  # file-system litter of archivers, not campaign data
        if stat.S_ISLNK(zi.external_attr >> 16):
            raise InputError(f"{name}: the entry {zi.filename!r} is a symbolic link; accepted is {accepted}")
        if zi.flag_bits & 0x1:
            raise InputError(f"{name} is encrypted; accepted is {accepted}, without a password")
        total += zi.file_size
        members.append((zi, parts))
    if len(members) > MAX_CAMPAIGN_FILES:
        raise InputError(f"{name} holds {len(members)} files, more than the {MAX_CAMPAIGN_FILES} accepted; accepted is {accepted}")
    if total > MAX_CAMPAIGN_UNPACKED_BYTES:
        raise InputError(f"{name} unpacks to {total / 2**20:.0f} MB, more than the {MAX_CAMPAIGN_UNPACKED_BYTES // 2**20} MB "
                         f"accepted; accepted is {accepted}")
    return members


def unpack_campaign_zip(contents, filename: str, root) -> str:
    """A campaign zip from a browser upload (``data:...;base64,...``) -> its upload id.

    The zip is unpacked into ``root/<id>`` (see :func:`upload_folder`), the id being a hash
    of its bytes, so the same upload lands in the same folder; the campaign is the
    shallowest folder holding a manifest.csv (the zip may hold the folder or its content).
    Raises InputError naming the file and what is accepted: not base64, too large, not a
    zip, damaged, unsafe entries (absolute paths, "..", links), too many or too large
    files, no manifest.csv, more than one campaign or manifest entries outside the campaign
    folder (:func:`dampersim.discrepancy.campaign.paths_outside`). Nothing is kept of a
    refused upload.
    """
    name = filename or "uploaded file"
    accepted = CAMPAIGN_ACCEPTED
    data = decode_upload(contents, name, accepted, MAX_CAMPAIGN_ZIP_BYTES, lambda n: f"{n / 2**20:.1f} MB",
                         size_accepted=f"a campaign zip of up to {MAX_CAMPAIGN_ZIP_BYTES // 2**20} MB here; diagnose a "
                                       "larger campaign on the server's command line with python -m dampersim diagnose "
                                       "CAMPAIGN")
    if not data:
        raise InputError(f"{name} is empty; accepted is {accepted}")
    buf = io.BytesIO(data)
    if not zipfile.is_zipfile(buf):
        raise InputError(f"{name} is not a zip archive; accepted is {accepted}")
    upload_id = hashlib.sha256(data).hexdigest()[:16]
    root = Path(root)
    if upload_folder(root, upload_id) is not None:
        return upload_id  # the same zip was unpacked before
    try:
        os.makedirs(root, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cache directory {str(root)!r} cannot be used ({exc.strerror or exc}); "
                         "set DAMPERSIM_CACHE_DIR to a writable folder") from None
    tmp = Path(tempfile.mkdtemp(prefix=f".{upload_id}-", dir=root))
    try:
        try:
            with zipfile.ZipFile(buf) as zf:
                members = _zip_members(zf, name, accepted)
                if not any(parts[-1] == MANIFEST for _zi, parts in members):
                    raise InputError(f"{name} holds no {MANIFEST}; accepted is {accepted}")
                budget = MAX_CAMPAIGN_UNPACKED_BYTES
                for zi, parts in members:
                    target = tmp.joinpath(*parts)
                    target.parent.mkdir(parents=True, exist_ok=True)
                    with zf.open(zi) as src, open(target, "wb") as dst:
                        while chunk := src.read(2**20):
                            budget -= len(chunk)
                            if budget < 0:  # the sizes in the archive's directory were wrong
                                raise InputError(f"{name} unpacks to more than {MAX_CAMPAIGN_UNPACKED_BYTES // 2**20} MB; "
                                                 f"accepted is {accepted}")
                            dst.write(chunk)
        except (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError, RuntimeError) as exc:
            raise InputError(f"{name} is a damaged or unsupported zip archive ({exc}); accepted is {accepted}") from None
        found = _manifest_dirs(tmp)
        if len(found) > 1:
            names = ", ".join(str(f.relative_to(tmp)) or "." for f in found)
            raise InputError(f"{name} holds {len(found)} campaigns ({names}); accepted is {accepted}")
        outside = paths_outside(found[0])  # an upload may only make the server read its own files
        if outside:
            row, rel = outside[0]
            raise InputError(f"{name}: {MANIFEST} row {row} [file]: {rel!r} lies outside the campaign folder; "
                             "accepted is a path relative to the folder, e.g. points/tc_1200.parquet")
        try:  # sizes from metadata only: nothing of the time series is loaded here
            scan_campaign(found[0], UPLOAD_LIMITS)
        except InputError as exc:
            raise InputError(f"{name}: {exc}") from None
        cname = str(read_campaign_json(found[0]).get("name") or found[0].name)[:200]
        size = folder_bytes(tmp)
        with quota_lock(root):
            make_room(root, size, keep=upload_id)
            dest = root / upload_id
            try:
                os.replace(tmp, dest)
            except OSError:
                if upload_folder(root, upload_id) is None:  # not a concurrent upload of the same zip
                    raise
            (root / f"{upload_id}.json").write_text(json.dumps({"filename": name, "name": cname, "bytes": size}),
                                                    encoding="utf-8")
        return upload_id
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


# --------------------------------------------------------------------------- quota
def folder_bytes(folder) -> int:
    """Bytes of the files under ``folder`` (links not followed)."""
    total = 0
    for sub, _dirs, files in os.walk(folder):
        for f in files:
            try:
                total += os.lstat(os.path.join(sub, f)).st_size
            except OSError:
                continue
    return total


@contextlib.contextmanager
def quota_lock(root):
    """Serialise quota decisions of concurrent uploads (also across server processes): an
    exclusive lock on a file beside the uploads folder."""
    try:
        import fcntl
    except ImportError:  # not POSIX: one process only
        yield
        return
    root = Path(root)
    with open(root.parent / f".{root.name}.lock", "a+b") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def list_uploads(root) -> list:
    """Uploads in ``root``, least recently used first: [{"id", "bytes", "used" (epoch s),
    "in_use"}]."""
    root = Path(root)
    try:
        entries = list(root.iterdir())
    except OSError:
        return []
    now = time.time()
    out = []
    for p in entries:
        if not (UPLOAD_ID.match(p.name) and p.is_dir() and not p.is_symlink()):
            continue
        meta = upload_metadata(root, p.name) or {}
        size = meta.get("bytes")
        if not isinstance(size, int) or size < 0:
            size = folder_bytes(p)
        try:
            used = (root / f"{p.name}.json").stat().st_mtime
        except OSError:
            used = p.stat().st_mtime
        out.append({"id": p.name, "bytes": size, "used": used,
                    "in_use": upload_in_use(root, p.name) or now - used < IN_USE_S})
    return sorted(out, key=lambda u: (u["used"], u["id"]))


def remove_upload(root, upload_id: str) -> None:
    """Remove an upload (its folder and metadata)."""
    root = Path(root)
    if not UPLOAD_ID.match(str(upload_id)):
        return
    (root / f"{upload_id}.json").unlink(missing_ok=True)
    shutil.rmtree(root / upload_id, ignore_errors=True)


def make_room(root, new_bytes: int, keep: str | None = None) -> list:
    """Evict the least recently used uploads of ``root`` until one more of ``new_bytes``
    fits the quota (:func:`upload_quota`); uploads in use and ``keep`` stay. Returns the
    ids removed. Raises InputError, removing nothing, when the quota cannot be met."""
    root = Path(root)
    max_n, max_bytes = upload_quota()
    uploads = [u for u in list_uploads(root) if u["id"] != keep]
    n, total = len(uploads) + 1, sum(u["bytes"] for u in uploads) + new_bytes
    if new_bytes > max_bytes:
        raise InputError(f"the campaign unpacks to {new_bytes / 2**20:.0f} MB, more than the {max_bytes / 2**20:.0f} MB "
                         "this server keeps for all uploads; diagnose it with python -m dampersim diagnose CAMPAIGN")
    plan = []
    for u in uploads:
        if n <= max_n and total <= max_bytes:
            break
        if u["in_use"]:
            continue
        plan.append(u["id"])
        n, total = n - 1, total - u["bytes"]
    if n > max_n or total > max_bytes:
        raise InputError(f"this server's space for uploaded campaigns is full ({len(uploads)} campaigns, "
                         f"{(total - new_bytes) / 2**20:.0f} MB, all in use; the quota is {max_n} campaigns and "
                         f"{max_bytes / 2**20:.0f} MB): nothing was removed; try again when a diagnosis has finished")
    for uid in plan:
        remove_upload(root, uid)
    return plan


@contextlib.contextmanager
def upload_in_use_by(root, upload_id):
    """Mark an upload as in use (never evicted) while the ``with`` block runs, e.g. while a
    diagnosis reads it; the mark names this process, so one left by a killed process
    expires."""
    path = Path(root) / f"{upload_id}{_BUSY}.{os.getpid()}.{time.monotonic_ns()}"
    try:
        path.write_text(str(os.getpid()), encoding="utf-8")
    except OSError:
        path = None
    try:
        yield
    finally:
        if path is not None:
            path.unlink(missing_ok=True)


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True
    return True


def upload_in_use(root, upload_id: str) -> bool:
    """Whether a living process marked the upload as in use (:func:`upload_in_use_by`)."""
    for p in Path(root).glob(f"{upload_id}{_BUSY}.*"):
        try:
            pid = int(p.name.split(".")[2])
        except (IndexError, ValueError):
            continue
        if _pid_alive(pid):
            return True
    return False


def cleanup_stale_uploads(root=None, max_age_s: float = STALE_TEMP_S) -> list:
    """Remove what interrupted uploads left in the uploads folder ``root`` (default:
    ``private_dir("uploads")``): temporary extraction folders older than ``max_age_s``
    seconds, in-use marks of processes that are gone, and metadata files without their
    upload. Returns the names removed. The server calls it at start-up."""
    if root is None:
        from dampersim.locations import private_dir

        root = private_dir("uploads")
    root = Path(root)
    try:
        entries = list(root.iterdir())
    except OSError:
        return []
    limit = time.time() - max_age_s
    removed = []
    for p in entries:
        try:
            if _TEMP.match(p.name) and p.is_dir() and not p.is_symlink():
                if p.stat().st_mtime < limit:
                    shutil.rmtree(p, ignore_errors=True)
                    removed.append(p.name)
            elif _BUSY + "." in p.name and p.is_file():
                parts = p.name.split(".")
                if len(parts) >= 3 and parts[2].isdigit() and not _pid_alive(int(parts[2])):
                    p.unlink(missing_ok=True)
                    removed.append(p.name)
            elif p.name.endswith(".json") and UPLOAD_ID.match(p.name[:-5]) and not (root / p.name[:-5]).is_dir():
                if p.stat().st_mtime < limit:
                    p.unlink(missing_ok=True)
                    removed.append(p.name)
        except OSError:
            continue
    return removed


__all__ = [
    "UPLOAD_LIMITS",
    "MAX_UPLOADS",
    "MAX_UPLOADS_BYTES",
    "IN_USE_S",
    "upload_quota",
    "list_uploads",
    "remove_upload",
    "make_room",
    "folder_bytes",
    "quota_lock",
    "upload_in_use_by",
    "upload_in_use",
    "cleanup_stale_uploads",
    "MAX_CAMPAIGN_ZIP_BYTES",
    "MAX_CAMPAIGN_FILES",
    "MAX_CAMPAIGN_UNPACKED_BYTES",
    "CAMPAIGN_ACCEPTED",
    "UPLOAD_ID",
    "decode_upload",
    "upload_folder",
    "upload_metadata",
    "unpack_campaign_zip",
]
