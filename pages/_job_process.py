"""What runs inside a job process of the dashboard's job queue, and how that process starts.

A job process is forked by a fork server (an exec'd interpreter with :data:`PRELOAD`
imported) or, in a process that cannot use that server, spawned; with the manager's
``start_method="fork"`` (a test's own app, a process that holds no SQLite connection in
another thread) it is forked from the server process itself and runs :func:`_job_main`
directly. It runs the callback function, writes progress, ``set_props`` and the result
under the job's keys of the result cache (:data:`KEY_PREFIX`), and only then tells the job
registry that the job has finished: a reader that sees the job finished and reads the
cache afterwards finds the result (see :meth:`pages._background.JobQueueManager.get_result`).
"""

from __future__ import annotations

import importlib
import inspect
import itertools
import multiprocessing
import os
import pickle
import signal
from contextvars import copy_context

import diskcache

from dampersim.incidents import public_message
from dampersim.jobs import JobRegistry

#: Prefix of a job's keys in the result cache (result, progress, set_props).
KEY_PREFIX = "dampersim-job-"
#: Seconds a finished job's result stays in the cache when a waiter never collects it.
RESULT_EXPIRE_S = 3600.0


class _JobFunction:
    """The callback ``fn`` as run inside a job process: progress and ``set_props`` go to
    the job's keys as ``(sequence, value)``, the result to the job's key; an exception is
    stored as a one-line public message (no traceback, no server path)."""

    def __init__(self, fn, progress):
        self.fn = fn
        self.progress = bool(progress)

    def run(self, cache, job_id, args, context) -> bool:
        from dash._callback_context import context_value
        from dash._utils import AttributeDict
        from dash.background_callback._proxy_set_props import ProxySetProps
        from dash.exceptions import PreventUpdate

        key = KEY_PREFIX + job_id
        counter = itertools.count(1)

        def set_progress(value):
            if not isinstance(value, (list, tuple)):
                value = [value]
            cache.set(key + "-progress", (next(counter), list(value)), expire=RESULT_EXPIRE_S)

        def set_props(_id, props):
            cache.set(key + "-set_props", (next(counter), {_id: props}), expire=RESULT_EXPIRE_S)

        extra = [set_progress] if self.progress else []

        def call():
            c = AttributeDict(**context)
            c.ignore_register_page = False
            c.updated_props = ProxySetProps(set_props)
            context_value.set(c)
            if isinstance(args, dict):
                out = self.fn(*extra, **args)
            elif isinstance(args, (list, tuple)):
                out = self.fn(*extra, *args)
            else:
                out = self.fn(*extra, args)
            if inspect.iscoroutine(out):
                import asyncio

                out = asyncio.run(out)
            return out

        try:
            result, ok = copy_context().run(call), True
        except PreventUpdate:
            result, ok = {"_dash_no_update": "_dash_no_update"}, True
        except Exception as exc:  # noqa: BLE001 - every failure becomes a public message
            result, ok = {"background_callback_error": {"msg": public_message(exc, "background job"), "tb": ""}}, False
        try:
            cache.set(key, result, expire=RESULT_EXPIRE_S)
        except Exception as exc:  # noqa: BLE001 - e.g. an unpicklable result, a full disk
            cache.set(key, {"background_callback_error": {"msg": public_message(exc, "background job result"),
                                                          "tb": ""}}, expire=RESULT_EXPIRE_S)
            ok = False
        return ok


def _job_main(job_fn, store_dir, registry, job_id, args, context):
    """Entry point of a job process: own session and process group, default signal
    handling, then run, store the result and tell the registry."""
    os.setsid()
    for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
        signal.signal(sig, signal.SIG_DFL)
    cache = diskcache.Cache(store_dir)
    ok = False
    try:
        ok = job_fn.run(cache, job_id, args, context)
    finally:
        cache.close()
        registry.finish(job_id, ok)


#: Modules the fork server imports once, so that a job process starts in a fraction of a
#: second (it still builds the app, which opens no connection shared with the server).
PRELOAD = ("numpy", "pandas", "scipy.signal", "numba", "plotly.graph_objects", "dash", "diskcache", "psutil",
           "dampersim.views.sweeps", "dampersim.views.hysteresis", "dampersim.views.discrepancy",
           "dampersim.views.segments", "dampersim.views.explorer", "dampersim.views.pulsation",
           "dampersim.views.studies")


#: Environment variables a job process takes from the server at the moment the job starts
#: (the fork server keeps the environment it was started with).
JOB_ENV_PREFIXES = ("DAMPERSIM_", "NUMBA_")


def job_environment() -> dict:
    """The server's settings a job must see: every ``DAMPERSIM_*`` and ``NUMBA_*`` variable."""
    return {k: v for k, v in os.environ.items() if k.startswith(JOB_ENV_PREFIXES)}


def _job_entry(blob, fn_key, app_module, store_dir, registry_folder, job_id, args, context, env=None):
    """Entry point of a job process started by the fork server: a fresh interpreter, so it
    carries no SQLite connection, lock or thread of the server (a process forked from the
    threaded server inherits SQLite's view of locks other threads hold, and its first
    cache write fails with "disk I/O error"). ``env``: the server's settings now
    (:func:`job_environment`), replacing those the fork server started with. The job
    function travels pickled when it can (a module-level function); when it cannot be
    pickled, or loading it fails (a page module imports only inside the app), it is found
    by its Dash key after importing ``app_module`` (which registers the callbacks)."""
    if env is not None:
        for key in [k for k in os.environ if k.startswith(JOB_ENV_PREFIXES) and k not in env]:
            del os.environ[key]
        os.environ.update(env)
    job_fn = None
    if blob is not None:
        try:
            job_fn = pickle.loads(blob)
        except Exception:  # noqa: BLE001 - e.g. a page module that registers a page on import
            job_fn = None
    if job_fn is None:
        job_fn = _registered_job_fn(fn_key, app_module)
    _job_main(job_fn, store_dir, JobRegistry(registry_folder), job_id, args, context)


def _registered_job_fn(fn_key, app_module):
    from dash.background_callback.managers import BaseBackgroundCallbackManager as Base

    def find():
        for key, fn, progress in Base.functions:
            if key == fn_key:
                return _JobFunction(fn, progress)
        return None

    found = find()
    if found is None and app_module:
        importlib.import_module(app_module)
        found = find()
    if found is None:
        raise LookupError(f"background callback {fn_key[:12]} is not defined by {app_module!r}")
    return found


_FORKSERVER = {"pid": None, "ctx": None}


def _forkserver():
    """The multiprocessing context of job processes: a fork server (an exec'd process with
    :data:`PRELOAD` imported) forks each job. A process forked from one that already
    started its fork server cannot use that server (it belongs to the parent): there,
    job processes are spawned (a fresh interpreter each, about a second slower to start,
    equally clean)."""
    owner = _FORKSERVER["pid"]
    if owner is not None and owner != os.getpid():
        return multiprocessing.get_context("spawn")
    if _FORKSERVER["ctx"] is None:
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(list(PRELOAD))
        _FORKSERVER.update(pid=os.getpid(), ctx=ctx)
    return _FORKSERVER["ctx"]
