"""Hostile uploads: campaign zips and parameter files that would make the server allocate
gigabytes or work for hours are refused from their metadata, before anything is loaded;
uploaded campaigns live under a quota; stale temporary folders are removed; a link does
not start a diagnosis above the auto-start budget; files above a page's limit are stopped
in the browser.

Budgets (each with its reason at the assertion): the refused 5-million-row Parquet zip
loaded 435 MB of RSS and took 0.9 s before the metadata caps (20 ms and under 3 MB after).
"""

from __future__ import annotations

import base64
import gc
import io
import json
import os
import re
import shutil
import stat
import subprocess
import time
import tracemalloc
import zipfile
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import app  # noqa: F401  (registers the pages and their callbacks)
from dampersim import views
from dampersim.discrepancy import campaign as C, upload as UP
from dampersim.discrepancy.campaign import MeasuredPoint
from dampersim.discrepancy.campaign_write import write_campaign
from dampersim.views.discrepancy import uploads_dir
from dampersim.errors import InputError, ParameterError
from dampersim.incidents import _PATH
from dampersim.parameters import default_parameters, io as pio
from pages import _uploads as U, discrepancy as D, parameters as P

HEADER = "id,kind,speed_rpm,mean_torque_nm,file,sample_rate_hz\n"
SERIES = ("time_s", "input_torque_nm", "output_torque_nm", "input_speed_rpm", "output_speed_rpm")


# ----------------------------------------------------------------------------- helpers
def data_url(data: bytes, kind="application/zip") -> str:
    return f"data:{kind};base64," + base64.b64encode(data).decode()


def zip_bytes(files: dict, infos: dict | None = None) -> bytes:
    """{name: bytes} (and {name: ZipInfo tweak}) -> zip bytes."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED, compresslevel=9) as zf:
        for name, data in files.items():
            zi = zipfile.ZipInfo(name)
            zi.compress_type = zipfile.ZIP_DEFLATED
            (infos or {}).get(name, lambda z: None)(zi)
            zf.writestr(zi, data)
    return buf.getvalue()


def as_text(obj) -> str:
    return json.dumps(obj, default=lambda c: c.to_plotly_json() if hasattr(c, "to_plotly_json") else str(c),
                      ensure_ascii=False)


def assert_clean(text: str, *folders) -> None:
    """No traceback and no absolute server path in a message a browser sees."""
    assert "Traceback" not in text and 'File "' not in text, text
    for f in folders:
        assert str(f) not in text, text
    assert not _PATH.search(text), text


def refused(contents, filename, cache) -> str:
    """The page's upload callback on a refused zip: returns its notice text after checking
    that nothing changed and nothing was kept."""
    options, value, notices = D.upload(contents, filename, [{"label": "x", "value": "hidden-effect-example"}])
    text = as_text(notices)
    assert options is dash_no_update() and value is dash_no_update(), text
    assert "The upload was refused" in text and filename in text, text
    assert_clean(text, cache)
    root = cache / views.UPLOADS_SUBDIR
    assert not root.exists() or not [p for p in root.iterdir() if p.is_dir()], "a refused upload left files"
    return text


def dash_no_update():
    from dash import no_update
    return no_update


def hostile_parquet(rows: int = 5_000_000) -> bytes:
    """A Parquet file of ``rows`` rows of the five series columns, all zeros: a few hundred
    kB on disk (run-length encoded), 200 MB as float64 arrays. Written in row groups so
    that building it stays small."""
    buf = io.BytesIO()
    chunk = pa.table({c: pa.array(np.zeros(500_000)) for c in SERIES})
    with pq.ParquetWriter(buf, chunk.schema, compression="zstd") as w:
        for _ in range(rows // 500_000):
            w.write_table(chunk)
    return buf.getvalue()


def point(pid, rpm=1500.0, torque=200.0, seconds=0.6, rate=5000.0):
    n = int(seconds * rate) + 1
    t = np.arange(n) / rate
    ripple = 50.0 * np.sin(2 * np.pi * 2 * rpm / 60.0 * t)
    return MeasuredPoint(id=pid, kind="torsional", speed_rpm=rpm, mean_torque_nm=torque, sample_rate_hz=rate, time=t,
                         input_torque=torque + ripple, output_torque=torque + 0.5 * ripple,
                         input_speed_rpm=np.full(n, rpm), output_speed_rpm=np.full(n, rpm))


def campaign_zip(tmp_path, name="c", points=None, fmt="parquet", seconds=0.6) -> bytes:
    """A small valid campaign (3 torsional points by default) as zip bytes."""
    folder = tmp_path / name
    pts = points or [point(f"p{i}", rpm=1000.0 + 300 * i, seconds=seconds) for i in range(3)]
    write_campaign(folder, pts, name=name, fmt=fmt)
    files = {f"{name}/{p.relative_to(folder).as_posix()}": p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}
    return zip_bytes(files)


@pytest.fixture(scope="module")
def warm():
    """Import and touch everything the measured calls use, so that the memory measured is
    the call's own, not the first import of pandas, pyarrow or the page modules."""
    C.file_shape  # noqa: B018
    pq.ParquetFile  # noqa: B018
    import pandas  # noqa: F401
    return True


def measured(fn):
    """(result or exception, seconds, tracemalloc peak [bytes], RSS growth [bytes])."""
    import psutil

    proc = psutil.Process()
    gc.collect()
    rss0 = proc.memory_info().rss
    tracemalloc.start()
    t0 = time.perf_counter()
    try:
        out = fn()
    except Exception as exc:  # noqa: BLE001 - returned for the test to look at
        out = exc
    took = time.perf_counter() - t0
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return out, took, peak, proc.memory_info().rss - rss0


# ----------------------------------------------------------------------------- the 5-million-row Parquet zip
def test_five_million_row_parquet_zip_is_refused_before_loading(cache_dir, warm):
    pq_bytes = hostile_parquet()
    contents = data_url(zip_bytes({"c/manifest.csv": HEADER + "a,torsional,1500,200,points/a.parquet,5000\n",
                                   "c/points/a.parquet": pq_bytes}))
    assert len(contents) < 20_000  # the attack: a link-sized upload (1.7 KB zip in the issue)
    out, took, peak, rss = measured(lambda: D.upload(contents, "hostile.zip", []))
    text = as_text(out[2])
    assert "The upload was refused" in text and "points/a.parquet" in text and "5000000 samples" in text, text
    assert "at most 1000000 samples per file" in text, text  # names the file, the count and the limit
    assert_clean(text, cache_dir)
    # Loading it took 435 MB of RSS (200 MB of float64 arrays plus Arrow's buffers) and 0.9 s;
    # the footer alone is a few kB: 40 MB of RSS and 8 MB of Python allocations leave room
    # for allocator noise and the zip's bytes, and still fail if the data were loaded.
    assert rss < 40 * 2**20, f"RSS grew by {rss / 2**20:.0f} MB"
    assert peak < 8 * 2**20, f"tracemalloc peak {peak / 2**20:.1f} MB"
    # 1 s: the page's request budget (measured 0.02 s; loading took 0.9 s on 2 cores)
    assert took < 1.0, f"{took:.2f} s"
    assert not any(p.is_dir() for p in (cache_dir / views.UPLOADS_SUBDIR).iterdir())  # nothing kept


def test_a_campaign_within_the_caps_is_accepted_and_listed(cache_dir, tmp_path):
    options, value, notices = D.upload(data_url(campaign_zip(tmp_path)), "good.zip", [])
    assert value.startswith(views.UPLOAD_PREFIX), as_text(notices)
    uid = value[len(views.UPLOAD_PREFIX):]
    root = cache_dir / views.UPLOADS_SUBDIR
    assert stat.S_IMODE(root.stat().st_mode) == 0o700  # a private folder (the server reads it back)
    meta = json.loads((root / f"{uid}.json").read_text())
    assert meta["name"] == "c" and meta["bytes"] > 0
    assert "3 of 3 test points valid" in as_text(D.report_for(value))


# ----------------------------------------------------------------------------- manifests
def test_a_file_listed_many_times_is_refused_naming_the_file_and_rows(cache_dir, tmp_path, warm):
    base = campaign_zip(tmp_path)
    with zipfile.ZipFile(io.BytesIO(base)) as zf:
        files = {n: zf.read(n) for n in zf.namelist()}
    rows = "".join(f"r{i},torsional,1000,200,points/p0.parquet,5000\n" for i in range(300))
    files["c/manifest.csv"] = (HEADER + rows).encode()
    out, took, _peak, _rss = measured(lambda: refused(data_url(zip_bytes(files)), "repeat.zip", cache_dir))
    assert isinstance(out, str), out
    assert "'points/p0.parquet' is listed 300 times" in out and "rows 2, 3, 4" in out and "and 290 more" in out, out
    assert took < 1.0, f"{took:.2f} s"  # the page's request budget: nothing is read 300 times


def test_the_command_line_reader_reads_a_repeated_file_once(tmp_path, monkeypatch):
    folder = tmp_path / "c"
    write_campaign(folder, [point("p0"), point("p1", rpm=1300.0)], name="c")
    (folder / "manifest.csv").write_text(HEADER + "p0,torsional,1500,200,points/p0.parquet,5000\n"
                                         + "".join(f"x{i},torsional,1500,200,./points/p0.parquet,5000\n" for i in range(50)))
    reads = []
    real = C._read_table
    monkeypatch.setattr(C, "_read_table", lambda path, columns=None: reads.append(path) or real(path, columns))
    camp = C.read_campaign(folder)
    assert [p.id for p in camp.points] == ["p0"] and len(reads) == 1  # one reading, not 51
    dup = [q for q in camp.problems if "already listed in row 2" in q.message]
    assert len(dup) == 50 and dup[0].file == "manifest.csv row 3"


def test_too_many_manifest_rows_are_refused(cache_dir):
    rows = "".join(f"p{i},torsional,1000,200,points/p{i}.parquet,5000\n" for i in range(501))
    text = refused(data_url(zip_bytes({"c/manifest.csv": HEADER + rows})), "rows.zip", cache_dir)
    assert "501 rows" in text and "at most 500" in text and "python -m dampersim diagnose" in text, text


def test_a_csv_with_a_huge_line_count_is_refused_from_a_bounded_count(cache_dir, warm):
    lines = b"0,0,0,0,0\n" * 3_000_000  # 30 MB of text, 30 kB zipped; 3 million samples
    files = {"c/manifest.csv": HEADER + "a,torsional,1500,200,points/a.csv,5000\n",
             "c/points/a.csv": ",".join(SERIES).encode() + b"\n" + lines}
    contents = data_url(zip_bytes(files))
    del lines, files
    out, took, peak, rss = measured(lambda: refused(contents, "lines.zip", cache_dir))
    assert isinstance(out, str), out
    assert "points/a.csv" in out and "more than 1000000 samples" in out, out
    # 30 MB unpacked to disk and counted in 1 MB chunks: parsing it would take ~200 MB and
    # ~2 s; 40 MB of RSS covers the zip's bytes in memory and allocator noise
    assert rss < 40 * 2**20 and peak < 40 * 2**20, (rss, peak)
    assert took < 2.0, f"{took:.2f} s"  # unzipping 30 MB (~0.2 s) and counting (~0.05 s), 2 cores shared


@pytest.mark.parametrize("shape, expect", [
    ({"seconds": 130.0, "rate": 1000.0}, "accepted are records of at most 120 s"),
    ({"n_files": 6, "seconds": 110.0, "rate": 1000.0}, "more than 600 s in all"),
])
def test_record_length_and_diagnosis_cost_are_capped(cache_dir, tmp_path, shape, expect):
    n = shape.get("n_files", 1)
    pts = [point(f"p{i}", seconds=shape["seconds"], rate=shape["rate"]) for i in range(n)]
    text = refused(data_url(campaign_zip(tmp_path, points=pts)), "long.zip", cache_dir)
    assert expect in text, text


def test_total_samples_are_capped(tmp_path):
    folder = tmp_path / "c"
    write_campaign(folder, [point(f"p{i}", seconds=20.0, rate=5000.0) for i in range(3)], name="c")  # 100 001 samples each
    limits = C.CampaignLimits(total_samples=150_000)
    with pytest.raises(InputError, match=r"points/p1\.parquet \(manifest\.csv row 3\): the campaign's files hold more "
                                         r"than 150000 samples in all"):
        C.scan_campaign(folder, limits)
    with pytest.raises(InputError):  # and the reader stops there too, before loading
        C.read_campaign(folder, limits=limits)


def test_a_forged_parquet_footer_length_is_refused(tmp_path):
    folder = tmp_path / "c"
    write_campaign(folder, [point("p0")], name="c")
    f = folder / "points" / "p0.parquet"
    data = bytearray(f.read_bytes())
    data[-8:-4] = (2**31 - 1).to_bytes(4, "little")  # a footer "of 2 GB"
    f.write_bytes(bytes(data))
    with pytest.raises(InputError, match="points/p0.parquet: a Parquet footer of 2147483647 bytes; accepted is at most 1 MB"):
        C.scan_campaign(folder, UP.UPLOAD_LIMITS)


# ----------------------------------------------------------------------------- what already held
def _bomb() -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
        zf.writestr("c/manifest.csv", HEADER)
        with zf.open("c/points/a.csv", "w", force_zip64=True) as fh:
            zero = bytes(2**22)
            for _ in range(70):  # 280 MB of zeros, ~280 kB compressed
                fh.write(zero)
    return buf.getvalue()


def _encrypted() -> bytes:
    """A zip whose entry carries the "encrypted" flag, as a password-protected archive has
    it (zipfile cannot write one: the flag is set in the local and central headers)."""
    data = bytearray(zip_bytes({"c/manifest.csv": HEADER}))
    for sig, off in ((b"PK\x03\x04", 6), (b"PK\x01\x02", 8)):
        i = data.find(sig)
        data[i + off] |= 0x01
    return bytes(data)


@pytest.mark.parametrize("files, infos, expect", [
    ({"../evil/manifest.csv": HEADER}, None, "points outside the archive"),
    ({"/abs/manifest.csv": HEADER}, None, "points outside the archive"),
    ({"c/manifest.csv": HEADER, "c/link": "/etc/passwd"},
     {"c/link": lambda zi: setattr(zi, "external_attr", (stat.S_IFLNK | 0o777) << 16)}, "is a symbolic link"),
    ("encrypted", None, "is encrypted"),
    ("bomb", None, "unpacks to 280 MB, more than the 256 MB accepted"),
])
def test_unsafe_archives_stay_refused(cache_dir, files, infos, expect):
    data = _bomb() if files == "bomb" else _encrypted() if files == "encrypted" else zip_bytes(files, infos)
    text = refused(data_url(data), "unsafe.zip", cache_dir)
    assert expect in text, text


# ----------------------------------------------------------------------------- quota and clean-up
def _age(root: Path, uid: str, seconds: float) -> None:
    t = time.time() - seconds
    os.utime(root / f"{uid}.json", (t, t))


def test_quota_evicts_the_least_recently_used_and_keeps_what_is_in_use(cache_dir, tmp_path, monkeypatch):
    monkeypatch.setenv("DAMPERSIM_UPLOADS_MAX", "2")
    root = uploads_dir()
    a = UP.unpack_campaign_zip(data_url(campaign_zip(tmp_path, "a")), "a.zip", root)
    b = UP.unpack_campaign_zip(data_url(campaign_zip(tmp_path, "b")), "b.zip", root)
    _age(root, a, 3 * UP.IN_USE_S)
    _age(root, b, 2 * UP.IN_USE_S)  # b is newer than a, but neither was used lately
    with UP.upload_in_use_by(root, a):  # a diagnosis is running on the oldest one
        c = UP.unpack_campaign_zip(data_url(campaign_zip(tmp_path, "c")), "c.zip", root)
        kept = {u["id"] for u in UP.list_uploads(root)}
        assert kept == {a, c}, "the oldest one not in use (b) goes; the one in use and the newest stay"
        assert UP.upload_folder(root, b) is None and UP.upload_folder(root, a) is not None
        # everything in use (a: diagnosed, c: uploaded just now): a new upload is refused, nothing removed
        with pytest.raises(InputError, match=r"space for uploaded campaigns is full .*nothing was removed"):
            UP.unpack_campaign_zip(data_url(campaign_zip(tmp_path, "d")), "d.zip", root)
        assert {u["id"] for u in UP.list_uploads(root)} == {a, c}
    assert not list(root.glob("*.busy.*"))  # the in-use mark goes with the diagnosis
    _age(root, a, 3 * UP.IN_USE_S)
    d = UP.unpack_campaign_zip(data_url(campaign_zip(tmp_path, "d")), "d.zip", root)
    assert {u["id"] for u in UP.list_uploads(root)} == {c, d}
    assert sorted(p.name for p in root.iterdir()) == sorted([c, f"{c}.json", d, f"{d}.json"])  # no metadata left over


def test_quota_in_bytes(cache_dir, tmp_path, monkeypatch):
    root = uploads_dir()
    a = UP.unpack_campaign_zip(data_url(campaign_zip(tmp_path, "a")), "a.zip", root)
    size = UP.list_uploads(root)[0]["bytes"]
    _age(root, a, 2 * UP.IN_USE_S)
    monkeypatch.setenv("DAMPERSIM_UPLOADS_MB", str(1.5 * size / 2**20))  # room for one campaign of this size
    b = UP.unpack_campaign_zip(data_url(campaign_zip(tmp_path, "b")), "b.zip", root)
    assert [u["id"] for u in UP.list_uploads(root)] == [b]
    monkeypatch.setenv("DAMPERSIM_UPLOADS_MB", "-3")
    with pytest.raises(InputError, match=r"DAMPERSIM_UPLOADS_MB='-3': accepted is a positive number"):
        UP.upload_quota()


def test_cleanup_removes_stale_temporary_folders_only(cache_dir, tmp_path):
    root = uploads_dir()
    keep = UP.unpack_campaign_zip(data_url(campaign_zip(tmp_path)), "c.zip", root)
    stale, fresh = root / ".0123456789abcdef-x1", root / ".0123456789abcdef-x2"
    for p in (stale, fresh):
        (p / "points").mkdir(parents=True)
        (p / "points" / "half.parquet").write_bytes(b"PAR1")
    old = time.time() - 2 * 3600
    os.utime(stale, (old, old))
    dead = subprocess.Popen(["true"])
    dead.wait()
    (root / f"{keep}.busy.{dead.pid}.1").write_text(str(dead.pid))  # left by a killed job
    orphan = root / "fedcba9876543210.json"
    orphan.write_text("{}")
    os.utime(orphan, (old, old))
    removed = UP.cleanup_stale_uploads(root, max_age_s=3600)
    assert sorted(removed) == sorted([stale.name, f"{keep}.busy.{dead.pid}.1", orphan.name])
    assert fresh.is_dir() and UP.upload_folder(root, keep) is not None  # a running upload and the campaigns stay
    assert UP.cleanup_stale_uploads(max_age_s=3600) == []  # default folder: private_dir("uploads")


# ----------------------------------------------------------------------------- the ?upload= autostart rule
def test_a_link_does_not_start_a_diagnosis_above_the_autostart_budget(cache_dir, tmp_path, monkeypatch):
    options, value, _ = D.upload(data_url(campaign_zip(tmp_path)), "c.zip", [])
    uid = value[len(views.UPLOAD_PREFIX):]
    summary = views.campaign_summary(views.upload_folder(uid))
    assert summary["ready"] and summary["torsional"] == 3
    from dampersim import costs
    from dampersim.discrepancy.effects import EFFECTS

    cost = costs.diagnosis_cost(default_parameters(), 3, summary["longest_s"], len(EFFECTS))
    monkeypatch.setenv(costs.AUTOSTART_ENV, str(2 * cost.work))
    out = D.request(False, True, [value], None, True)  # the page opened from ?upload=<id>
    assert out.get("job") is not None, out  # within the auto-start budget: starts
    monkeypatch.setenv(costs.AUTOSTART_ENV, str(cost.work / 2))
    out = D.request(False, True, [value], None, True)
    text = as_text(out["status"])
    assert "job" not in out and "Not started automatically" in text and cost.text() in text, text
    assert "Press Run diagnosis" in text and D.layout(upload=uid) is not None
    assert D.request(True, False, [value], None, True).get("job") is not None  # Run starts it
    monkeypatch.setenv(costs.BUDGET_ENV, str(cost.work / 2))  # above the server budget: never
    out = D.request(True, False, [value], None, True)
    assert "job" not in out and "this server accepts at most" in as_text(out["status"])
    done = D.job({"state": {"campaign": None, "upload": uid}}, lambda *a: None)  # a crafted job request
    assert "this server accepts at most" in done["error"] and "python -m dampersim diagnose" in done["error"]
    assert "no longer on this server" in D.job({"state": {"upload": "../../etc"}}, lambda *a: None)["error"]


# ----------------------------------------------------------------------------- parameter files
def test_a_parameter_file_with_5000_rig_elements_is_refused_without_an_eigen_solve(cache_dir, monkeypatch):
    text = pio.dumps_toml(default_parameters())
    text += "".join(f'[[rig.elements]]\nname = "e{i}"\ninertia = 0.1\n'
                    for i in range(5000 - len(default_parameters().rig.elements)))
    assert len(text.encode()) < views.params.MAX_UPLOAD_BYTES  # within the page's 256 kB: the size check lets it in
    calls = []
    monkeypatch.setattr(np.linalg, "eigvals", lambda *a, **k: calls.append(1) or pytest.fail("eigen-solve ran"))
    t0 = time.perf_counter()
    out = P.parameters_action("upload", [], None, data_url(text.encode(), "application/toml"), "rig.toml")
    took = time.perf_counter() - t0
    msg = as_text(out["notices"])
    assert out["params"] is None and "rig.elements" in msg and "5000 elements" in msg and "at most 64" in msg, msg
    assert_clean(msg, cache_dir)
    assert not calls
    # 0.5 s: parsing 200 kB of TOML takes ~0.1 s; building and checking 5000 elements and the
    # eigen-solve over 5000+ DOFs (minutes) are what the cap avoids
    assert took < 0.5, f"{took:.2f} s"


def test_degrees_of_freedom_match_the_solver_and_are_capped(monkeypatch):
    from dampersim.parameters import validation, with_updates
    from dampersim.solver.layout import build_layout

    sets = [default_parameters(),
            with_updates(default_parameters(), {"effects.clutch_slip.enabled": True, "effects.pendulum_absorber.enabled": True,
                                                "solver.outer_segments": 30})]
    for s in sets:
        assert validation.degrees_of_freedom(s) == build_layout(s, 150.0).ndof
    monkeypatch.setattr(validation, "MAX_DEGREES_OF_FREEDOM", 30)
    with pytest.raises(ParameterError, match=r"solver = '86 degrees of freedom': accepted is at most 30"):
        validation.validate(sets[0])  # 86 with the default 48/16 segments


def test_oversize_toml_and_deep_nesting_are_parameter_errors():
    with pytest.raises(ParameterError, match="at most 1048576 characters"):
        pio.loads_toml("#" * (pio.MAX_TOML_CHARS + 1))
    with pytest.raises(ParameterError, match="valid TOML"):
        pio.loads_toml("a = " + "[" * 100_000 + "]" * 100_000)


# ----------------------------------------------------------------------------- size checks
SERVER_INPUTS = ("discrepancy-upload.contents", "discrepancy-import-upload.contents", "parameters-upload.contents")


def test_no_server_callback_receives_the_raw_upload():
    """The browser posts a file only through the size check's store: no server callback
    takes an upload's contents as input or state (it would be posted whatever its size)."""
    import app

    app.app._setup_server()  # moves the pages' callbacks into the app's list (idempotent)
    callbacks = app.app._callback_list
    for cb in callbacks:
        if cb.get("clientside_function"):
            continue
        ids = [f"{d['id']}.{d['property']}" for d in cb.get("inputs", []) + cb.get("state", [])]
        assert not set(ids) & set(SERVER_INPUTS), cb["output"]
    clientside = [cb for cb in callbacks if cb.get("clientside_function")
                  and cb["inputs"][0]["id"] in ("discrepancy-upload", "discrepancy-import-upload", "parameters-upload")]
    assert len(clientside) == 3


@pytest.mark.skipif(shutil.which("node") is None, reason="node runs the browser's size check outside a browser")
def test_the_browser_size_check_stops_large_files_and_passes_small_ones():
    js = U.size_check_js(10 * 2**20, "Diagnose it with python -m dampersim diagnose CAMPAIGN.")
    big = "data:application/zip;base64," + "A" * (4 * (11 * 2**20) // 3)
    small = "data:application/zip;base64," + base64.b64encode(b"x" * 1000).decode()
    script = ("var window = {dash_clientside: {no_update: 'NO_UPDATE'}};\nvar f = " + js + ";\n"
              f"console.log(JSON.stringify([f({json.dumps(big)}, 'big.zip'), f({json.dumps(small)}, 's.zip'), f(null, null)]));")
    out = json.loads(subprocess.run(["node"], input=script, capture_output=True, text=True, check=True, timeout=30).stdout)
    data, text, style = out[0]
    assert data == "NO_UPDATE" and style == {}  # not posted; the notice shows
    assert text == ("The file big.zip is 11.0 MB; this page accepts up to 10 MB. Diagnose it with python -m dampersim "
                    "diagnose CAMPAIGN. The file was not sent to the server."), text
    assert out[1][0]["filename"] == "s.zip" and out[1][0]["contents"] == small and out[1][2] == {"display": "none"}
    assert out[2] == ["NO_UPDATE"] * 3


def test_the_server_still_refuses_an_oversize_upload_before_decoding(cache_dir):
    big = "data:application/zip;base64," + "A" * (4 * (12 * 2**20) // 3)  # 12 MB: past a browser without the check
    t0 = time.perf_counter()
    text = refused(big, "big.zip", cache_dir)
    assert "big.zip is 12.0 MB" in text and "up to 10 MB" in text and "python -m dampersim diagnose" in text, text
    assert time.perf_counter() - t0 < 0.5  # refused from the text's length: 16 MB are not decoded
    out = P.parameters_action("upload", [], None, "data:text/plain;base64," + "A" * 400_000, "big.toml")
    assert "big.toml is 293 kB" in as_text(out["notices"]) and "256 kB" in as_text(out["notices"])
