"""The Discrepancy page's data: which campaign (a bundled example or an upload), the
campaign's validation report, and the cached diagnosis of :mod:`dampersim.discrepancy`
with its figures.

Uploaded zips are unpacked by :mod:`dampersim.discrepancy.upload` under
``private_dir("uploads")/<id>`` (a 0700 folder of the cache), where the id is a hash of the
zip's bytes, so the same upload lands in the same folder; the uploads quota evicts the
least recently used ones. Every campaign the page reads is first checked from metadata
against :data:`dampersim.discrepancy.upload.UPLOAD_LIMITS`, so reading it for the
validation report stays bounded in time and memory.

Cost rule of the diagnosis (:func:`diagnosis_admission`): its cost is estimated by
:func:`dampersim.costs.diagnosis_cost` (model runs of the diagnosis times steps x DOF of
its longest record) and judged by :func:`dampersim.costs.admit`: above the server budget
it is refused (also on Run); above the auto-start budget it does not start from a link
(``?upload=`` or ``?campaign=``): the page shows the estimate and the Run button. The diagnosis document and its wording come from
:mod:`dampersim.discrepancy.report`.
"""

from __future__ import annotations

import copy
import functools
import hashlib
import os
import time
from pathlib import Path
from urllib.parse import quote

from dampersim.discrepancy import upload
from dampersim.discrepancy.campaign import MANIFEST, read_campaign
from dampersim.discrepancy.diagnose import INSUFFICIENT, MIN_TORSIONAL_POINTS, diagnose, shortfall
from dampersim.discrepancy.drive import Runner
from dampersim.discrepancy.report import (
    diagnosis_document,
    diagnosis_from_document,
    has_point_data,
    ranking_rows,
    verdict_summary,
)
from dampersim.discrepancy.upload import CAMPAIGN_ACCEPTED, UPLOAD_ID, UPLOAD_LIMITS
from dampersim.errors import InputError
from dampersim.parameters import default_parameters, with_updates
from dampersim.plotting import discrepancy as diagnosis_plots
from dampersim.locations import private_dir, repo_root
from dampersim.views.notices import notice, query_value
from dampersim.views.store import cached_view, view_key

#: Sub-directory of the cache with the unpacked campaign uploads (a private folder).
UPLOADS_SUBDIR = "uploads"
#: Keyword arguments of :func:`dampersim.discrepancy.diagnose.diagnose` used by the
#: dashboard (empty: the library's defaults); part of the cache key.
DISCREPANCY_OPTIONS: dict = {}
#: Bumped when the content of a cached diagnosis view changes shape (2: the campaign
#: summary says what a campaign lacks, ``missing`` and ``message``; 3: the likelihood, posterior,
#: detectability and next test points).
DISCREPANCY_FORMAT = 3
#: Default example campaign of the page (the first bundled one if it is missing).
DEFAULT_EXAMPLE = "hidden-effect-example"
#: Rough cost of the diagnosis [core seconds per second of torsional record], measured
#: on the bundled example (12 points of 1 s, no ramp) with
#: ``python -m dampersim diagnose examples/campaigns/hidden-effect-example --json``: 878 s on 2
#: idle cores and 1872 model runs with the leading effect's re-calibration stepping at each
#: iteration's own robust weights (naming.Namer.refit), so 146 core seconds per second, taken
#: as 155 so that the estimate errs long (two runs of the earlier re-calibration, 2024 model
#: runs each, differed by 3 %), with the solver settings DIAGNOSIS_MEASURED; other settings
#: scale it by a test point's step·DOF. With the re-calibration at the calibrated model's
#: weights it was 165 (955 s, 2024 runs on commit 0d89dbf), before that step 140 (820 s and
#: 1792 runs on commit 81b62b5), and 46 at 18/8 segments on commit dd443e3 (278 s, 1676
#: runs), which scaled to 48/16 had come to err short (595 s against 820 s) as the diagnosis
#: came to run every point more often
DIAGNOSIS_CORE_S_PER_RECORD_S = 155.0
#: set-up of a diagnosis in the page's time estimate [s] (reading the campaign, starting workers)
DIAGNOSIS_SETUP_S = 2.0
#: solver settings of the DIAGNOSIS_CORE_S_PER_RECORD_S measurement: the default set's 48/16
#: segments and 1/120 000 s step [s]
DIAGNOSIS_MEASURED = {"solver.outer_segments": 48, "solver.inner_segments": 16, "solver.time_step": 1.0 / 120000.0}
#: Dropdown values of uploads: this prefix and the upload id.
UPLOAD_PREFIX = "upload:"


def example_campaigns_dir() -> Path:
    """Folder of the bundled example campaigns (``examples/campaigns`` of the checkout)."""
    return repo_root() / "examples" / "campaigns"


def example_campaigns(root=None) -> dict:
    """Bundled example campaigns: folder name -> path (folders holding a manifest.csv)."""
    root = Path(root) if root is not None else example_campaigns_dir()
    try:
        entries = sorted(root.iterdir())
    except OSError:
        return {}
    return {p.name: p for p in entries if p.is_dir() and (p / MANIFEST).is_file()}


def default_example(examples: dict):
    """The example a page shows first (None when nothing is bundled)."""
    return DEFAULT_EXAMPLE if DEFAULT_EXAMPLE in examples else next(iter(examples), None)



# --------------------------------------------------------------------------- uploads
def uploads_dir() -> Path:
    """Folder of the unpacked campaign uploads of this server: ``private_dir("uploads")``
    (created 0700, refused when another user owns it or others may write to it)."""
    return private_dir(UPLOADS_SUBDIR)


def unpack_campaign_zip(contents, filename: str = "campaign.zip") -> str:
    """A campaign zip from a browser upload -> its upload id, unpacked into
    :func:`uploads_dir` by :func:`dampersim.discrepancy.upload.unpack_campaign_zip` (which
    says what it refuses and why)."""
    return upload.unpack_campaign_zip(contents, filename, uploads_dir())


def upload_folder(upload_id):
    """Campaign folder of an earlier upload, or None (unknown id, cleared cache or evicted)."""
    if not isinstance(upload_id, str) or not UPLOAD_ID.match(upload_id):
        return None
    try:
        root = uploads_dir()
    except InputError as exc:  # a cache folder refused (owner, mode): logged, the page falls back
        from dampersim.incidents import report

        report(exc, "uploads folder")
        return None
    return upload.upload_folder(root, upload_id)


def upload_in_use(state: dict):
    """A context manager that keeps the upload of a page state from being evicted while the
    ``with`` block runs (nothing for a bundled example)."""
    import contextlib

    if state.get("upload") and UPLOAD_ID.match(str(state["upload"])):
        return upload.upload_in_use_by(uploads_dir(), state["upload"])
    return contextlib.nullcontext()


def upload_label(upload_id: str) -> str:
    """Dropdown label of an upload: its file name and campaign name when known."""
    meta = upload.upload_metadata(uploads_dir(), upload_id)
    if meta is None:
        return f"uploaded campaign {upload_id}"
    return f"uploaded: {meta.get('name') or upload_id} ({meta.get('filename') or 'zip'})"


# --------------------------------------------------------------------------- page state
def parse_discrepancy_query(query: dict | None, examples: dict) -> tuple:
    """The Discrepancy page's query -> ``(state, notices)``.

    Keys: ``campaign`` (a bundled example's folder name) or ``upload`` (the id of a
    campaign uploaded to this server; it wins over ``campaign``). A refused value gives a
    notice naming the key, the value, what is accepted and what is used instead; unknown
    keys are ignored. ``state`` = {"campaign": name or None, "upload": id or None}.
    """
    state, notices, _folder = _discrepancy_query(query, examples)
    return state, notices


def _discrepancy_query(query: dict | None, examples: dict) -> tuple:
    """:func:`parse_discrepancy_query` plus the campaign folder it resolved (see
    :func:`discrepancy_folder`): ``(state, notices, folder or None)``."""
    query = dict(query or {})
    notices: list = []
    fallback = default_example(examples)
    used = f"the example {fallback}" if fallback else "no campaign (upload one)"
    state = {"campaign": fallback, "upload": None}
    if "upload" in query:
        raw = query_value(query, "upload", notices, "Uploaded campaign")
        text = str(raw).strip()
        if not UPLOAD_ID.match(text):
            notices.append(notice(f"Uploaded campaign (upload={raw!r}) is not an upload id: accepted is the 16 hex digits "
                                  f"the page writes into the link after an upload. Using {used}."))
        elif (folder := upload_folder(text)) is None:
            notices.append(notice(f"Uploaded campaign (upload={raw!r}) is not on this server (uploads live in the cache, "
                                  f"which may have been cleared): upload the zip again. Using {used}."))
        else:
            return {"campaign": None, "upload": text}, notices, folder
    if "campaign" in query:
        raw = query_value(query, "campaign", notices, "Example campaign")
        if isinstance(raw, str) and raw in examples:
            state["campaign"] = raw
        else:
            names = ", ".join(examples) if examples else "(none bundled with this installation)"
            notices.append(notice(f"Example campaign (campaign={raw!r}) is not a bundled example: accepted is one of {names}. "
                                  f"Using {used}."))
    if not examples:
        notices.append(notice("No example campaigns are bundled with this installation: upload a campaign.", "info"))
    return state, notices, discrepancy_folder(state, examples)


def discrepancy_choice(value, examples: dict) -> tuple:
    """A campaign dropdown value (example name or ``upload:<id>``) -> ``(state, notices,
    folder)``: the state and notices of :func:`parse_discrepancy_query` and the campaign
    folder (:func:`discrepancy_folder`, resolved once) or None."""
    if isinstance(value, str) and value.startswith(UPLOAD_PREFIX):
        return _discrepancy_query({"upload": value[len(UPLOAD_PREFIX):]}, examples)
    return _discrepancy_query({"campaign": value} if value is not None else {}, examples)


def discrepancy_value(state: dict):
    """Dropdown value of a state (inverse of :func:`discrepancy_choice`)."""
    return UPLOAD_PREFIX + state["upload"] if state.get("upload") else state.get("campaign")


def discrepancy_query(state: dict) -> str:
    """Query string (with "?") of a Discrepancy page state."""
    if state.get("upload"):
        return "?upload=" + quote(state["upload"], safe="")
    if state.get("campaign"):
        return "?campaign=" + quote(state["campaign"], safe="._-")
    return ""


def discrepancy_folder(state: dict, examples: dict):
    """Campaign folder of a state, or None."""
    if state.get("upload"):
        return upload_folder(state["upload"])
    path = examples.get(state.get("campaign") or "")
    return Path(path) if path is not None else None


def summarise_campaign(camp) -> dict:
    """Validation report of a campaign already read (a
    :class:`dampersim.discrepancy.campaign.Campaign`), JSON-ready: see :func:`campaign_summary`.
    Whether it can be diagnosed is the diagnosis's own rule,
    :func:`dampersim.discrepancy.diagnose.shortfall` (enough valid torsional points, at more
    than one speed), so the page never starts a diagnosis that would end in
    ``insufficient_data`` for the campaign's shape."""
    rep = camp.report()
    missing, message = shortfall(camp.torsional, len(camp.ramps))
    return {"name": camp.name, "description": camp.description, "rows": rep["rows"], "valid": len(camp.points),
            "torsional": len(camp.torsional), "ramps": len(camp.ramps),
            "record_s": float(sum(p.duration for p in camp.torsional)),
            "longest_s": float(max((p.duration for p in camp.torsional), default=0.0)),
            "ramp_s": float(max((p.duration for p in camp.ramps), default=0.0)),
            "problems": rep["problems"], "error": None, "ready": not missing, "missing": missing,
            "message": message}


def not_ready_text(summary: dict) -> str:
    """What a campaign that is not ready for the diagnosis (its :func:`campaign_summary`)
    lacks and what is accepted, to follow a colon: the message of
    :func:`dampersim.discrepancy.diagnose.shortfall` without its "not diagnosed: " lead."""
    text = summary.get("message") or (f"{summary.get('torsional', 0)} valid torsional test point(s) are not enough "
                                      "for a diagnosis.")
    return text.removeprefix("not diagnosed: ")


def _folder_files(folder: Path) -> tuple:
    """((relative path, size, mtime_ns), ...) of every file under ``folder`` in a fixed
    order: the memo key of :func:`campaign_summary` and :func:`campaign_digest`, so a
    changed, added or removed file gives a new key."""
    out = []
    for sub, dirs, files in os.walk(folder):
        dirs.sort()
        for f in sorted(files):
            p = Path(sub) / f
            try:
                st = p.stat()
            except OSError:
                continue  # gone since the walk
            out.append((p.relative_to(folder).as_posix(), st.st_size, st.st_mtime_ns))
    return tuple(out)


def campaign_summary(folder) -> dict:
    """Validation report of the campaign in ``folder``, JSON-ready.

    {"name", "description", "rows", "valid", "torsional", "ramps", "record_s", "problems"
    (each with file, field, point, message), "error" (a campaign that cannot be read at
    all), "ready" (the diagnosis can run: enough valid torsional points, at more than one
    speed), "missing" (what it lacks: "torsional_points", "speeds"; empty when ready) and
    "message" (what it lacks and what is accepted, in words; "" when ready)}. Paths in messages
    are relative to the campaign folder (the server's folders are not shown). Memoised
    per process on the folder and the size and modification time of its files.
    """
    folder = Path(folder)
    return copy.deepcopy(_campaign_summary(str(folder), _folder_files(folder)))


@functools.lru_cache(maxsize=32)
def _campaign_summary(folder: str, _files: tuple) -> dict:
    folder = Path(folder)
    try:
        camp = read_campaign(folder, limits=UPLOAD_LIMITS)
    except InputError as exc:
        msg = str(exc).replace(str(folder) + os.sep, "").replace(str(folder), folder.name)
        return {"name": folder.name, "description": "", "rows": 0, "valid": 0, "torsional": 0, "ramps": 0,
                "record_s": 0.0, "problems": [], "error": msg, "ready": False, "missing": [], "message": ""}
    return summarise_campaign(camp)


def diagnosis_seconds(record_s: float, cores: int | None = None, system=None) -> float:
    """Rough wall time [s] of diagnosing torsional records of ``record_s`` seconds in all
    with the parameter set ``system`` (default set if None)."""
    from dampersim import costs

    cores = cores or Runner(None).workers
    system = system or default_parameters()
    measured = with_updates(system, DIAGNOSIS_MEASURED, check=False)
    scale = costs.point_cost(system, 1.0, record_segments=False).work / costs.point_cost(
        measured, 1.0, record_segments=False).work
    return DIAGNOSIS_SETUP_S + DIAGNOSIS_CORE_S_PER_RECORD_S * scale * float(record_s) / max(1, cores)


def ramp_share(seconds: float, ramp_work: float, torsional_work: float) -> float:
    """The estimate ``seconds`` [s] of :func:`diagnosis_seconds` (DIAGNOSIS_SETUP_S plus the
    torsional records' share) with the ramps' runs added: the records' share grows by
    ``ramp_work`` / ``torsional_work``, the cost model's work [step·DOF] that the ramps add and
    its work for the torsional records alone."""
    if torsional_work <= 0.0:
        return seconds
    return seconds + (seconds - DIAGNOSIS_SETUP_S) * max(0.0, ramp_work) / torsional_work


def diagnosis_admission(summary: dict, started_by_link: bool) -> tuple:
    """The cost rule for diagnosing a campaign (its :func:`campaign_summary`): ``("run",
    text)``, ``("ask", text)`` (the cost model's work, :func:`dampersim.costs.diagnosis_cost`,
    above the auto-start budget and started by a link, not by Run: show the text and the Run
    button) or ``("refuse", text)`` (above the server budget; :func:`dampersim.costs.admit`).
    The text's time estimate grows with the seconds of torsional record
    (:func:`diagnosis_seconds`) and with the ramps' share of the cost model's work
    (:func:`ramp_share`); it informs, the budgets decide."""
    from dampersim import costs
    from dampersim.discrepancy.effects import EFFECTS

    system = default_parameters()
    n_candidates = len(DISCREPANCY_OPTIONS.get("candidates") or EFFECTS)
    n_points, longest = int(summary.get("torsional") or 0), float(summary.get("longest_s") or 0.0)
    record_s = float(summary.get("record_s") or 0.0)
    cost = costs.diagnosis_cost(system, n_points, longest, n_candidates, int(summary.get("ramps") or 0),
                                float(summary.get("ramp_s") or 0.0))
    # the measured estimate covers torsional records only, by their total length; the ramps'
    # runs (and the torsional re-run after their sizing) add what the cost model gives them,
    # against its torsional work at the records' mean length (the bound above uses the longest)
    ramp_work = cost.work - costs.diagnosis_cost(system, n_points, longest, n_candidates).work
    mean = costs.diagnosis_cost(system, n_points, record_s / max(1, n_points), n_candidates)
    est = ramp_share(diagnosis_seconds(record_s, system=system), ramp_work, mean.work)
    what = (f"{summary.get('torsional', 0)} torsional test points, {float(summary.get('record_s') or 0):.3g} s of "
            f"record: {cost.text()}, about {est:.0f} s on this server")
    try:
        rule = costs.admit(cost)
    except costs.BudgetError as exc:
        return "refuse", (f"This diagnosis is not run here: {exc}. Diagnose the campaign on the command line with "
                          "python -m dampersim diagnose CAMPAIGN.")
    if started_by_link and rule == "ask":
        return "ask", (f"Not started automatically: {what}, above the auto-start budget of this server "
                       f"({costs.AUTOSTART_ENV}). Press Run diagnosis to start it.")
    return "run", what


def campaign_digest(folder) -> str:
    """SHA-256 of every file of a campaign folder (relative path and bytes); memoised per
    process on the folder and the size and modification time of its files."""
    folder = Path(folder)
    return _campaign_digest(str(folder), _folder_files(folder))


@functools.lru_cache(maxsize=32)
def _campaign_digest(folder: str, files: tuple) -> str:
    h = hashlib.sha256()
    for rel, _size, _mtime in files:
        h.update(rel.encode() + b"\0")
        with open(Path(folder, rel), "rb") as fh:
            for chunk in iter(lambda: fh.read(2**20), b""):
                h.update(chunk)
        h.update(b"\0")
    return h.hexdigest()



# --------------------------------------------------------------------------- diagnosis
def discrepancy_key(folder, system=None) -> str:
    """Cache key of a diagnosis: campaign files, parameter set, options, code, platform and
    version (a :func:`view_key` of kind "discrepancy")."""
    state = {"format": DISCREPANCY_FORMAT, "campaign": campaign_digest(folder), "options": DISCREPANCY_OPTIONS}
    return view_key("discrepancy", system or default_parameters(), state, module=__name__)


def discrepancy_figures(doc: dict) -> dict:
    """Figures (plain dicts) of a diagnosis document: ``gap``, ``ranking`` and, when the
    document holds per-point data, ``map``, ``profile`` and ``overlays`` (else None).
    A campaign that could not be diagnosed (``insufficient_data``) has no numbers to draw:
    every figure is None."""
    if doc.get("verdict") == INSUFFICIENT:
        return dict.fromkeys(("gap", "ranking", "map", "profile", "overlays"))
    d = diagnosis_from_document(doc)
    gap = diagnosis_plots.gap_figure(d, None)
    ranking = diagnosis_plots.ranking_figure(d, None)
    out = {"gap": gap.to_dict(), "ranking": ranking.to_dict()}
    full = has_point_data(doc)
    out["map"] = diagnosis_plots.residual_map_figure(d, None).to_dict() if full else None
    out["profile"] = diagnosis_plots.residual_profile_figure(d, None).to_dict() if full else None
    out["overlays"] = diagnosis_plots.held_out_overlay_figure(d, None).to_dict() if full else None
    return out


def _discrepancy_view_key(folder, system=None, **_):
    return discrepancy_key(folder, system)


@cached_view(_discrepancy_view_key)
def discrepancy_view(folder, progress=None, cache_only: bool = False, workers=None, system=None):
    """The diagnosis of the campaign in ``folder`` for the page, cached.

    Returns {"key", "campaign" (see :func:`campaign_summary`), "diagnosis" (see
    :func:`dampersim.discrepancy.report.diagnosis_document`), "summary"} or, with
    ``cache_only``, None on a miss. ``progress(fraction, text)`` is passed to the diagnosis.
    A campaign that cannot be diagnosed (too few valid torsional points, all at one speed,
    or too few left once failed model runs are left out) is no error: its diagnosis has
    the verdict ``insufficient_data``, and ``message`` and ``missing`` say what it lacks.
    The page checks the campaign's shape first (``ready`` of :func:`campaign_summary`) and
    does not start such a diagnosis. Raises InputError only for a campaign that cannot be
    read.
    """
    if cache_only:
        return None
    t0 = time.perf_counter()
    camp = read_campaign(folder, limits=UPLOAD_LIMITS)
    summary = summarise_campaign(camp)  # the campaign just read, not a second reading
    diag = diagnose(camp, system, workers=workers, progress=progress, **DISCREPANCY_OPTIONS)
    doc = diagnosis_document(diag)
    return {
        "kind": "discrepancy",
        "campaign": summary,
        "diagnosis": doc,
        "summary": {"compute_time_s": time.perf_counter() - t0, "simulations": diag.simulations},
    }


__all__ = [
    "UPLOADS_SUBDIR",
    "UPLOAD_PREFIX",
    "CAMPAIGN_ACCEPTED",
    "DISCREPANCY_OPTIONS",
    "MIN_TORSIONAL_POINTS",
    "example_campaigns",
    "default_example",
    "uploads_dir",
    "unpack_campaign_zip",
    "upload_folder",
    "upload_label",
    "parse_discrepancy_query",
    "discrepancy_choice",
    "discrepancy_value",
    "discrepancy_query",
    "discrepancy_folder",
    "summarise_campaign",
    "campaign_summary",
    "not_ready_text",
    "diagnosis_seconds",
    "ramp_share",
    "diagnosis_admission",
    "upload_in_use",
    "campaign_digest",
    "discrepancy_key",
    "discrepancy_figures",
    "discrepancy_view",
    "ranking_rows",
    "verdict_summary",
]
