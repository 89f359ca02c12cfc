"""Background-callback manager of the dashboard: Dash's diskcache manager behind the job
registry of :mod:`dampersim.jobs`.

Dash's ``DiskcacheManager`` forks one process per background call, with no limit, and
lets it run after the tab is closed. :func:`make_manager` returns a manager whose jobs go
through the registry instead, before any process exists:

* a call queues a job; its process starts only when a slot is free (global and
  per-session limits), on that call or on a later poll, from whichever server process
  receives the poll (the registry and the job's arguments are on disk, so several WSGI
  workers share one queue);
* a call whose work key, computed on the server by ``work_of(args)`` (the dashboard
  reads it from the ticket's stored request; never from what the browser posts), equals
  that of a queued or running job of the same callback shares that job: no second
  process, and its result reaches every waiter (it is stored under the job's own key;
  each Dash cache key finds it through the registry); without ``work_of`` nothing is shared;
* a call above the queue caps (per session, in total) is answered at once with
  ``refused_result(message, args)`` (default: an error result), and no process starts;
* a job process runs in its own session and process group, recorded by pid and creation
  time, so terminating it also ends its pool workers and never hits a reused pid;
* a job nobody polls for ``idle_timeout_s`` seconds is terminated (or dropped from the
  queue); cancel (or a newer call replacing an old one) detaches one waiter and ends the
  job only when nobody else waits for it;
* a failing job stores :func:`dampersim.incidents.public_message` of its exception, never
  a traceback; a job whose process died without a result is reported as failed. What runs
  inside a job process, and how it starts, is :mod:`pages._job_process`.

Sessions are signed cookies (:mod:`pages._sessions`): requests without a cookie, or with
an unsigned or forged one, share one anonymous session. :func:`shutdown_jobs` terminates
the jobs this server process started (registered with :mod:`atexit`; also call it from
the server's signal handlers).
"""

from __future__ import annotations

import atexit
import hashlib
import importlib
import logging
import multiprocessing
import os
import pickle
import sqlite3
import threading
import time
from collections import OrderedDict

import diskcache
from dash import DiskcacheManager

from dampersim.incidents import public_message, redact_paths
from dampersim.jobs import ACTIVE, DONE, FAILED, QUEUED, JobRegistry
from pages._job_process import KEY_PREFIX as _KEY_PREFIX
from pages._job_process import RESULT_EXPIRE_S, _forkserver, _job_entry, _job_main, _JobFunction, job_environment
from pages._sessions import (ANONYMOUS, SESSION_COOKIE, current_session, install_sessions, sign_session,
                             verified_session)

LOGGER = logging.getLogger("dampersim.dashboard.jobs")

#: Seconds between two reaps by one server process (polls arrive every 0.3-1 s).
REAP_INTERVAL_S = 1.0
#: Seconds between two dispatch attempts by one server process.
DISPATCH_INTERVAL_S = 0.2
#: Seconds between two heartbeats of one waiter by one server process.
HEARTBEAT_INTERVAL_S = 1.0
#: Message for a job whose process ended without storing a result.
DIED_TEXT = ("the job stopped without a result (its process ended: killed, out of memory or crashed); "
             "press Run to try again")
#: Message for a finished job whose result is no longer in the cache.
GONE_TEXT = "the job's result is no longer in the cache (it was cleared meanwhile); press Run to compute it again"
_UNDEFINED = DiskcacheManager.UNDEFINED
_MANAGERS: list = []
_ATEXIT = []


def first_argument(args):
    """The first callback argument of a background call (Dash passes a list, or a dict)."""
    if isinstance(args, (list, tuple)):
        return args[0] if args else None
    return next(iter(args.values()), None) if isinstance(args, dict) else args


def refused_error(message: str, _args=None) -> dict:
    """Default result of a refused submission: a background-callback error."""
    return {"background_callback_error": {"msg": message, "tb": ""}}


def _slim_context(context) -> dict:
    """The callback context a job needs, without the request's cookies and headers (the
    session cookie is not written to disk)."""
    out = dict(context)
    out["cookies"], out["headers"] = {}, {}
    return out


#: How Dash starts the message of a background callback's error (dash._callback).
_DASH_ERROR_PREFIX = "An error occurred inside a background callback: "


def job_error_text(exc) -> str:
    """The text a page shows for the error of a background callback (its ``on_error``):
    the job queue stores only public messages (a refusal such as a full queue, a job that
    died, or :func:`dampersim.incidents.public_message` of the job's exception), so that
    message is shown as it is; any other exception goes through ``public_message``."""
    from dash.exceptions import BackgroundCallbackError

    if isinstance(exc, BackgroundCallbackError):
        text = str(exc)
        text = text[len(_DASH_ERROR_PREFIX):] if text.startswith(_DASH_ERROR_PREFIX) else text
        return redact_paths(text.strip().splitlines()[0] if text.strip() else "the job failed")
    return public_message(exc, "background job")


def _sanitise(result):
    """A stored error result with its traceback and paths removed (results written by
    other job functions, e.g. Dash's own)."""
    if isinstance(result, dict) and isinstance(result.get("background_callback_error"), dict):
        msg = str(result["background_callback_error"].get("msg", ""))
        return {"background_callback_error": {"msg": redact_paths(msg.splitlines()[0] if msg else "error"), "tb": ""}}
    return result


def default_queued_progress(n_outputs: int, text: str) -> list:
    """Progress values of a queued job for ``n_outputs`` progress outputs in the pages'
    order (value, max, text): a bar at 0 of 1 and ``text`` in the third output."""
    values = ["0", "1", text][:n_outputs]
    return values + [None] * (n_outputs - len(values))


# --------------------------------------------------------------------------- the manager
class JobQueueManager(DiskcacheManager):
    """Dash background-callback manager over :class:`dampersim.jobs.JobRegistry`; the job
    handle Dash gets (and signs) is the id of a *waiter*, not a pid. Build it with
    :func:`make_manager`."""

    def __init__(self, cache, registry: JobRegistry, *, queued_progress=None, start_method="forkserver",
                 app_module="app", work_of=None, refused_result=None):
        if start_method not in ("forkserver", "fork"):
            raise ValueError(f"start_method = {start_method!r}: accepted is 'forkserver' or 'fork'")
        self.registry = registry
        self.start_method = start_method
        self.app_module = app_module
        self.queued_progress = queued_progress or default_queued_progress
        self.work_of = work_of
        self.refused_result = refused_result or refused_error
        self._store = str(cache.directory)
        self._procs: dict = {}
        self._lock = threading.Lock()
        self._last_reap = self._last_dispatch = 0.0
        self._beats: OrderedDict = OrderedDict()
        self._seen: OrderedDict = OrderedDict()
        super().__init__(cache)

    # ----- Dash's job function registry
    def make_job_fn(self, fn, progress, key=None):
        return _JobFunction(fn, progress)

    def _fn_key(self, job_fn):
        for key, value in self.func_registry.items():
            if value is job_fn:
                return key
        raise LookupError("background callback is not registered with this manager")

    # ----- submit
    def call_job_fn(self, key, job_fn, args, context):
        """Queue (or share) the job; returns the waiter id Dash hands to the browser. The
        work key comes from ``work_of(args)`` on the server (nothing posted is trusted);
        a refused submission gets its result at once."""
        fn_key = self._fn_key(job_fn)
        work = None
        if self.work_of is not None:
            try:
                work = self.work_of(args)
            except Exception as exc:  # noqa: BLE001 - no key: the job is simply not shared
                LOGGER.warning("work key: %s", exc)
        work_key = hashlib.sha256(f"{fn_key}\0{work}".encode()).hexdigest() if isinstance(work, str) and work else None
        payload = pickle.dumps((fn_key, args, _slim_context(context)), protocol=pickle.HIGHEST_PROTOCOL)
        sub = self.registry.submit(current_session(self.registry.folder), work_key, store=self._store,
                                   payload=payload, cache_key=key)
        if sub.refused:
            self.handle.set(_KEY_PREFIX + sub.job_id, self.refused_result(sub.refused, args), expire=RESULT_EXPIRE_S)
            return sub.waiter_id
        self._tick(dispatch=True)
        return sub.waiter_id

    # ----- processes
    def _start(self, job_id, payload):
        fn_key, args, context = pickle.loads(payload)  # written by call_job_fn into the 0700 registry
        job_fn = self.func_registry.get(fn_key)
        if job_fn is None:
            raise LookupError(f"background callback {fn_key[:12]} is not registered in this server process")
        if self.start_method == "fork":
            proc = multiprocessing.get_context("fork").Process(
                target=_job_main, args=(job_fn, self._store, self.registry, job_id, args, context),
                name=f"dampersim-job-{job_id}")
        else:
            try:  # a module-level function travels by reference; a closure is found by its key
                blob = pickle.dumps(job_fn, protocol=pickle.HIGHEST_PROTOCOL)
            except (pickle.PicklingError, AttributeError, TypeError):
                blob = None
            proc = _forkserver().Process(
                target=_job_entry,
                args=(blob, fn_key, self.app_module, self._store, str(self.registry.folder), job_id, args, context,
                      job_environment()),
                name=f"dampersim-job-{job_id}")
        proc.start()
        with self._lock:
            self._procs[job_id] = proc
        return proc.pid

    def _reap_children(self):
        """Collect the exit status of finished job processes this server process forked."""
        with self._lock:
            for job_id, proc in list(self._procs.items()):
                if not proc.is_alive():
                    proc.join(0)
                    del self._procs[job_id]

    def _tick(self, dispatch=False):
        """Reap (at most every second) and start queued jobs (at most every 0.2 s, or now)."""
        now = time.monotonic()
        try:
            self._reap_children()
            if now - self._last_reap >= REAP_INTERVAL_S:
                self._last_reap = now
                self.registry.reap()
            if dispatch or now - self._last_dispatch >= DISPATCH_INTERVAL_S:
                self._last_dispatch = now
                self.registry.dispatch(self._start, store=self._store)
        except (sqlite3.Error, OSError, LookupError) as exc:  # a busy registry must not break a poll
            LOGGER.warning("job registry: %s", exc)

    def _beat(self, waiter):
        now = time.monotonic()
        if now - self._beats.get(waiter, 0.0) < HEARTBEAT_INTERVAL_S:
            return
        self._beats[waiter] = now
        self._beats.move_to_end(waiter)
        while len(self._beats) > 10000:
            self._beats.popitem(last=False)
        try:
            self.registry.heartbeat(waiter)
        except sqlite3.Error as exc:
            # not recorded: the next poll tries again instead of a second later, or a busy
            # registry would age the waiter's last poll towards the idle timeout
            self._beats.pop(waiter, None)
            LOGGER.warning("job registry heartbeat: %s", exc)

    def _fresh(self, name, seq):
        """True (and remembered) when ``seq`` of ``name`` was not returned yet."""
        if self._seen.get(name) == seq:
            return False
        self._seen[name] = seq
        self._seen.move_to_end(name)
        while len(self._seen) > 10000:
            self._seen.popitem(last=False)
        return True

    # ----- Dash's polling interface
    def job_running(self, job):
        if job is None:
            return False
        self._beat(str(job))
        self._tick()
        info = self.registry.waiter(str(job))
        if info is None or info.detached or info.collected:
            return False
        # a job that finished between this poll's get_result and now still "runs" for this
        # waiter until it has its result (or failure): otherwise Dash would stop polling
        return info.state in ACTIVE or info.state in (DONE, FAILED)

    def terminate_job(self, job):
        """Cancel from the page (or a newer call replacing this one): detach the waiter;
        the job ends only when no other waiter polls for it."""
        if job is None:
            return
        self.registry.cancel(str(job))

    def terminate_unhealthy_job(self, job):
        return False  # dead job processes are found by the registry's reap

    def _waiter(self, key, job=None):
        if job is not None:
            info = self.registry.waiter(str(job))
            if info is not None:
                return info
        return self.registry.waiter_for_cache_key(key) if key is not None else None

    def result_ready(self, key):
        info = self._waiter(key)
        return info is not None and self.handle.get(_KEY_PREFIX + info.job_id) is not None

    def get_result(self, key, job):
        info = self._waiter(key, job)
        if info is None or info.detached:
            return _UNDEFINED
        self._beat(info.waiter_id)
        self._tick()
        result = self.handle.get(_KEY_PREFIX + info.job_id, _UNDEFINED)
        if result is _UNDEFINED:
            if self._answered(info):
                return _UNDEFINED
            state = self.registry.job_state(info.job_id)
            if state not in (DONE, FAILED):
                return _UNDEFINED
            # a job stores its result before it is marked finished: it may have done both since the first read
            result = self.handle.get(_KEY_PREFIX + info.job_id, _UNDEFINED)
            if result is _UNDEFINED:
                if self._answered(info):  # a poll in flight collected it meanwhile
                    return _UNDEFINED
                # finished without a result (died), or its result was removed meanwhile (cache cleared)
                result = {"background_callback_error": {"msg": DIED_TEXT if state == FAILED else GONE_TEXT, "tb": ""}}
        if self.registry.collect(info.waiter_id):
            for suffix in ("", "-progress", "-set_props"):
                self.handle.delete(_KEY_PREFIX + info.job_id + suffix)
        return _sanitise(result)

    def _answered(self, info) -> bool:
        """Whether this waiter was answered, read again from the registry: a poll in flight may
        have collected its result since ``info`` was read, and the last collect removes it."""
        return (self.registry.waiter(info.waiter_id) or info).collected

    def get_progress(self, key):
        info = self._waiter(key)
        if info is None or info.detached:
            return None
        if info.state == QUEUED:
            text = self._queued_text(info)
            if not self._fresh(("p", key), text):
                return None
            return self.queued_progress(_progress_outputs(), text)
        stored = self.handle.get(_KEY_PREFIX + info.job_id + "-progress")
        if not stored or not self._fresh(("p", key), stored[0]):
            return None
        return stored[1]

    def _queued_text(self, info) -> str:
        pos = self.registry.queue_position(info.job_id)
        if pos is None:
            return "starting"
        ahead, running = pos
        if ahead:
            return f"queued: {ahead} job{'s' if ahead != 1 else ''} ahead"
        if self.registry.session_running(info.session) >= self.registry.limits.per_session:
            return f"queued: your other jobs run first (at most {self.registry.limits.per_session} at once per session)"
        if running >= self.registry.limits.max_jobs:
            return f"queued: waiting for a free slot ({running} jobs running)"
        return "queued: starting"

    def get_updated_props(self, key):
        info = self._waiter(key)
        if info is None:
            return {}
        stored = self.handle.get(_KEY_PREFIX + info.job_id + "-set_props")
        if not stored or not self._fresh(("s", key), stored[0]):
            return {}
        return stored[1]

    # ----- server exit
    def shutdown(self) -> list:
        """Terminate the jobs this server process started; returns their ids."""
        ids = self.registry.shutdown(os.getpid())
        with self._lock:
            procs = list(self._procs.values())
            self._procs.clear()
        for proc in procs:
            proc.join(timeout=1.0)
        return ids

    def close(self) -> list:
        """:meth:`shutdown`, then forget this manager: :func:`shutdown_jobs` no longer
        reaches it and Dash registers no further callbacks with it (a server keeps its
        manager for life; tests build and close many). Returns the ids of the jobs ended."""
        from dash.background_callback.managers import BaseBackgroundCallbackManager

        ids = self.shutdown()
        for registry in (_MANAGERS, BaseBackgroundCallbackManager.managers):
            if self in registry:
                registry.remove(self)
        return ids


def _progress_outputs() -> int:
    """Number of progress outputs of the callback this request polls (3 when unknown)."""
    try:
        from dash import get_app
        from flask import has_request_context, request

        if has_request_context():
            body = request.get_json(silent=True) or {}
            spec = get_app().callback_map.get(body.get("output"), {}).get("background") or {}
            if spec.get("progress"):
                return len(spec["progress"])
    except Exception:  # noqa: BLE001 - only a display detail
        pass
    return 3


def make_manager(cache_root, *, max_jobs=None, per_session=None, idle_timeout_s=None, registry_dir=None,
                 queued_progress=None, start_method="forkserver", app_module="app", work_of=None,
                 refused_result=None, queued_per_session=None, max_queued=None) -> JobQueueManager:
    """Background-callback manager whose jobs go through the job registry.

    cache_root: folder of the result cache (created 0700 when missing; it holds pickles,
        so it should be ``dampersim.locations.private_dir("callbacks")``).
    max_jobs, per_session, idle_timeout_s: limits (see :class:`dampersim.jobs.Limits`;
        defaults from ``$DAMPERSIM_MAX_JOBS``, ``$DAMPERSIM_JOBS_PER_SESSION``, cores, 2, 30 s).
    registry_dir: folder of the registry (default ``private_dir("jobs")``).
    queued_progress: ``(n_outputs, text) -> list`` of progress values of a queued job.
    start_method: "forkserver" (default: job processes forked by a clean fork server, see
        :func:`_job_entry`) or "fork" (forked from this process: only for a process that
        holds no SQLite connection in another thread, e.g. a test's own app).
    app_module: module whose import defines the background callbacks (the dashboard's
        ``app``), imported by a job process that cannot receive its function pickled.
    work_of: ``args -> work key or None``, computed on the server (never from posted
        data); calls of one callback with the same key share one job. None: no sharing.
    refused_result: ``(message, args) -> result`` of a call refused because the queue is
        full (default :func:`refused_error`); queued_per_session, max_queued: the caps.
    """
    os.makedirs(cache_root, mode=0o700, exist_ok=True)
    registry = JobRegistry(registry_dir, max_jobs=max_jobs, per_session=per_session, idle_timeout_s=idle_timeout_s,
                           queued_per_session=queued_per_session, max_queued=max_queued)
    manager = JobQueueManager(diskcache.Cache(str(cache_root)), registry, queued_progress=queued_progress,
                              start_method=start_method, app_module=app_module, work_of=work_of,
                              refused_result=refused_result)
    _MANAGERS.append(manager)
    if not _ATEXIT:
        # after multiprocessing's own exit handler, so it runs first (atexit is last in,
        # first out): that handler waits for non-daemon children, i.e. for running jobs
        importlib.import_module("multiprocessing.util")

        atexit.register(shutdown_jobs)
        _ATEXIT.append(True)
    return manager


def shutdown_jobs() -> list:
    """Terminate every job this server process started (all managers); for atexit and
    the server's signal handlers. Returns the job ids."""
    ids = []
    for manager in list(_MANAGERS):
        try:
            ids += manager.shutdown()
        except sqlite3.Error as exc:
            LOGGER.warning("job registry at shutdown: %s", exc)
    return ids


__all__ = ["SESSION_COOKIE", "ANONYMOUS", "JobQueueManager", "make_manager", "install_sessions", "current_session",
           "sign_session", "verified_session", "first_argument", "refused_error", "shutdown_jobs",
           "default_queued_progress", "job_error_text"]
