"""Unpacking a campaign uploaded from a browser: the zip arrives base64-encoded and is checked
(size, entries, one campaign, nothing outside its folder) before anything is kept.

Uploads live in a folder the caller chooses (the dashboard: its cache), one sub-folder
per upload named by the first 16 hex digits of the SHA-256 of the zip, with a small JSON
file beside it holding the file and campaign names.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import re
import shutil
import stat
import tempfile
import zipfile
import zlib
from pathlib import Path, PurePosixPath

from dampersim.discrepancy.campaign import MANIFEST, paths_outside, read_campaign
from dampersim.errors import InputError
from dampersim.uploads import decode_upload

#: Largest campaign zip accepted [bytes] (the dashboard's server refuses requests above
#: 16 MB and the browser sends the file base64-encoded, 4/3 of its size).
MAX_CAMPAIGN_ZIP_BYTES = 10 * 2**20
#: Most files, and most bytes once unpacked, of one uploaded campaign (refused before
#: anything is written, so an archive that expands enormously is never unpacked).
MAX_CAMPAIGN_FILES = 2000
MAX_CAMPAIGN_UNPACKED_BYTES = 256 * 2**20

CAMPAIGN_ACCEPTED = (f"a .zip (up to {MAX_CAMPAIGN_ZIP_BYTES // 2**20} MB) of one campaign folder: manifest.csv with the "
                     "columns id, kind, speed_rpm, mean_torque_nm, file, sample_rate_hz, the time series it lists "
                     "(.parquet or .csv) and optionally campaign.json (see docs/discrepancy.md)")
#: An upload id: 16 hex digits.
UPLOAD_ID = re.compile(r"^[0-9a-f]{16}$")


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
    return found[0] if len(found) == 1 else None


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
    data = decode_upload(contents, name, accepted, MAX_CAMPAIGN_ZIP_BYTES, lambda n: f"{n / 2**20:.1f} MB")
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
        try:
            cname = read_campaign(found[0]).name
        except InputError:
            cname = found[0].name  # the validation report on the page says what is wrong
        dest = root / upload_id
        try:
            os.replace(tmp, dest)
        except OSError:
            if upload_folder(root, upload_id) is None:  # not a concurrent upload of the same zip
                raise
        (root / f"{upload_id}.json").write_text(json.dumps({"filename": name, "name": cname}), encoding="utf-8")
        return upload_id
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


__all__ = [
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
