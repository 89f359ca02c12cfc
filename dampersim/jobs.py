"""Job registry: a bounded, shared queue of background jobs that several server processes
agree on.

Every job (one background computation of the dashboard) is a row in a SQLite database
under ``private_dir("jobs")`` (WAL journal, busy timeout), so that every server process
serving the dashboard (several WSGI workers, or a server restarted meanwhile) sees the same
jobs, and no limit depends on the memory of one process. Each operation below is one
transaction.

* :meth:`JobRegistry.submit` queues a job for a session, or, when a queued or running job
  has the same work key, attaches the caller to it as another *waiter* (no new process).
  The queue is capped per session and in total: above a cap the job is refused at once
  (recorded as failed, with the reason; no process).
* :meth:`JobRegistry.dispatch` starts queued jobs, oldest first, while fewer than
  ``max_jobs`` run in total and fewer than ``per_session`` run for the job's session; the
  other jobs stay queued (no process exists for them). The caller supplies the function
  that starts the process; the registry records its pid and its creation time, so a pid
  reused by an unrelated process is never signalled. A process whose job was cancelled
  between its claim and that record is terminated at once.
* :meth:`JobRegistry.heartbeat` records that a waiter still polls. :meth:`JobRegistry.reap`
  cancels jobs nobody has polled for ``idle_timeout_s`` seconds (terminating the process
  and its whole process group, i.e. its pool workers, or dropping it from the queue), and
  marks as failed running jobs whose process ended without reporting.
* :meth:`JobRegistry.cancel` detaches one waiter; the job itself is cancelled only when no
  other waiter still polls for it. :meth:`JobRegistry.shutdown` terminates every job a
  server process started (for its exit).
* :meth:`JobRegistry.sweep_workers` says how many cores a sweep started inside a job may
  use so that all running jobs together stay within the machine.

Settings: ``max_jobs`` (default: the number of usable cores, or ``$DAMPERSIM_MAX_JOBS``),
``per_session`` (default 2, or ``$DAMPERSIM_JOBS_PER_SESSION``), ``idle_timeout_s``
(default 30 s; dashboards poll every 0.3-1 s), ``queued_per_session`` (default 4) and
``max_queued`` (default 64). A bad value raises
:class:`~dampersim.errors.InputError` naming the variable, the value and what is accepted.

Job processes are expected to call :func:`os.setsid` first, so that the process id is
also the id of a process group holding everything the job started (see
:mod:`dampersim.jobprocs`, which signals them).
"""

from __future__ import annotations

import logging
import os
import secrets
import sqlite3
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from dampersim.errors import InputError
from dampersim.jobprocs import TERM_GRACE_S, process_alive, process_ctime, terminate_tree, usable_cores

LOGGER = logging.getLogger("dampersim.jobs")

#: Environment variable: most jobs running at once on this machine (whole number).
MAX_JOBS_ENV = "DAMPERSIM_MAX_JOBS"
#: Environment variable: most jobs running at once for one browser session (whole number).
PER_SESSION_ENV = "DAMPERSIM_JOBS_PER_SESSION"
#: Default per-session limit.
DEFAULT_PER_SESSION = 2
#: Default seconds without a poll after which a job is cancelled.
DEFAULT_IDLE_TIMEOUT_S = 30.0
#: Upper bound of both limits (a typo such as 10000 would otherwise mean "no limit").
MAX_LIMIT = 1024
#: Seconds a SQLite transaction waits for another process's lock before giving up.
BUSY_TIMEOUT_S = 10.0
#: Seconds finished jobs (and their waiters) stay in the registry, for late polls.
KEEP_FINISHED_S = 3600.0
#: Seconds a claimed job may stay without a recorded process before it counts as failed.
START_GRACE_S = 30.0
#: Default most queued (not yet running) jobs of one session; more are refused.
DEFAULT_QUEUED_PER_SESSION = 4
#: Default most queued jobs in total; more are refused.
DEFAULT_MAX_QUEUED = 64
#: Upper bound of the total queue cap.
MAX_QUEUED_LIMIT = 65536

QUEUED, RUNNING, DONE, FAILED, CANCELLED = "queued", "running", "done", "failed", "cancelled"
ACTIVE = (QUEUED, RUNNING)
STATES = (QUEUED, RUNNING, DONE, FAILED, CANCELLED)

_SCHEMA = """
CREATE TABLE IF NOT EXISTS jobs (
    seq INTEGER PRIMARY KEY AUTOINCREMENT,
    id TEXT UNIQUE NOT NULL,
    work_key TEXT,
    session TEXT NOT NULL,
    store TEXT NOT NULL,
    state TEXT NOT NULL,
    pid INTEGER,
    pid_ctime REAL,
    owner INTEGER,
    created REAL NOT NULL,
    started REAL,
    finished REAL,
    last_polled REAL NOT NULL,
    payload BLOB
);
CREATE INDEX IF NOT EXISTS jobs_state ON jobs (state);
CREATE INDEX IF NOT EXISTS jobs_work ON jobs (work_key, state);
CREATE TABLE IF NOT EXISTS waiters (
    id TEXT PRIMARY KEY,
    job_id TEXT NOT NULL,
    cache_key TEXT,
    session TEXT NOT NULL,
    created REAL NOT NULL,
    last_polled REAL NOT NULL,
    detached INTEGER NOT NULL DEFAULT 0,
    collected INTEGER NOT NULL DEFAULT 0
);
CREATE INDEX IF NOT EXISTS waiters_job ON waiters (job_id);
CREATE INDEX IF NOT EXISTS waiters_cache ON waiters (cache_key, created);
"""


# --------------------------------------------------------------------------- settings
def _whole(name: str, value, lo: int, hi: int) -> int:
    accepted = f"a whole number from {lo} to {hi}"
    if isinstance(value, bool):
        raise InputError(f"{name} = {value!r}: accepted is {accepted}")
    try:
        number = int(str(value).strip()) if not isinstance(value, int) else value
    except ValueError:
        raise InputError(f"{name} = {str(value)[:40]!r}: accepted is {accepted}") from None
    if not lo <= number <= hi:
        raise InputError(f"{name} = {str(value)[:40]!r}: accepted is {accepted}")
    return number


def _setting(name: str, env: str, value, default: int, lo: int, hi: int) -> int:
    """An explicit value, else the environment variable (if set and not blank), else the
    default; each checked against [lo, hi]."""
    if value is not None:
        return _whole(name, value, lo, hi)
    raw = os.environ.get(env)
    if raw is not None and raw.strip():
        return _whole(env, raw, lo, hi)
    return default


@dataclass(frozen=True)
class Limits:
    """Validated settings of a registry: ``max_jobs`` running jobs in total,
    ``per_session`` per browser session, cancel after ``idle_timeout_s`` [s] unpolled;
    at most ``queued_per_session`` queued jobs per session and ``max_queued`` in total."""

    max_jobs: int
    per_session: int
    idle_timeout_s: float
    queued_per_session: int = DEFAULT_QUEUED_PER_SESSION
    max_queued: int = DEFAULT_MAX_QUEUED

    @classmethod
    def resolve(cls, max_jobs=None, per_session=None, idle_timeout_s=None, queued_per_session=None,
                max_queued=None) -> "Limits":
        """Explicit values first, then ``$DAMPERSIM_MAX_JOBS`` / ``$DAMPERSIM_JOBS_PER_SESSION``,
        then the defaults (usable cores, 2, 30 s, 4 and 64 queued)."""
        jobs = _setting("max_jobs", MAX_JOBS_ENV, max_jobs, usable_cores(), 1, MAX_LIMIT)
        session = _setting("per_session", PER_SESSION_ENV, per_session, DEFAULT_PER_SESSION, 1, MAX_LIMIT)
        idle = DEFAULT_IDLE_TIMEOUT_S if idle_timeout_s is None else idle_timeout_s
        try:
            idle = float(idle)
        except (TypeError, ValueError):
            raise InputError(f"idle_timeout_s = {idle!r}: accepted is a number of seconds from 0.1 to 86400") from None
        if not 0.1 <= idle <= 86400:
            raise InputError(f"idle_timeout_s = {idle!r}: accepted is a number of seconds from 0.1 to 86400")
        queued = DEFAULT_QUEUED_PER_SESSION if queued_per_session is None else _whole(
            "queued_per_session", queued_per_session, 1, MAX_LIMIT)
        total = DEFAULT_MAX_QUEUED if max_queued is None else _whole("max_queued", max_queued, 1, MAX_QUEUED_LIMIT)
        return cls(jobs, session, idle, queued, total)


# --------------------------------------------------------------------------- registry
@dataclass(frozen=True)
class Submitted:
    """Outcome of :meth:`JobRegistry.submit`: the job, the caller's waiter handle,
    whether an existing job was shared, and why it was refused (the queue was full: the
    job is recorded as failed, no process starts), else None."""

    job_id: str
    waiter_id: str
    shared: bool
    refused: str | None = None


@dataclass(frozen=True)
class WaiterInfo:
    """A waiter and the job it waits for (``state`` is the job's state; ``collected``:
    the waiter received the result)."""

    waiter_id: str
    job_id: str
    state: str
    detached: bool
    session: str
    collected: bool = False


@dataclass(frozen=True)
class ReapReport:
    """Job ids a :meth:`JobRegistry.reap` cancelled for idleness (``idle``: running ones
    terminated, ``dropped``: queued ones removed) and marked ``failed``."""

    idle: tuple = ()
    dropped: tuple = ()
    failed: tuple = ()


def _enable_wal(con: sqlite3.Connection, budget_s: float) -> None:
    """Switch ``con``'s database to write-ahead logging (persistent: a no-op once done),
    retrying for up to ``budget_s`` [s]. The switch needs the database to itself, and SQLite
    reports it locked at once, without waiting its busy timeout, when another process opens
    or switches a new registry at the same moment (two server processes, or test workers,
    starting together: 2 of 240 openers failed in 30 rounds of 8 before this retry)."""
    deadline = time.monotonic() + budget_s
    while True:
        try:
            con.execute("PRAGMA journal_mode=WAL")
            return
        except sqlite3.OperationalError as exc:
            if "locked" not in str(exc) or time.monotonic() > deadline:
                raise
            time.sleep(0.01)


class JobRegistry:
    """The shared job table in ``folder/registry.sqlite3`` (default
    ``private_dir("jobs")``); see the module docstring."""

    def __init__(self, folder: str | os.PathLike | None = None, *, max_jobs=None, per_session=None,
                 idle_timeout_s=None, queued_per_session=None, max_queued=None):
        self.limits = Limits.resolve(max_jobs, per_session, idle_timeout_s, queued_per_session, max_queued)
        if folder is None:
            from dampersim.locations import private_dir

            folder = private_dir("jobs")
        self.folder = Path(folder)
        os.makedirs(self.folder, mode=0o700, exist_ok=True)
        self.path = self.folder / "registry.sqlite3"
        self._local = threading.local()
        self._con().executescript(_SCHEMA)  # idempotent; executescript commits by itself

    # ----- connection: one per thread and process (a connection never crosses a fork)
    def _con(self) -> sqlite3.Connection:
        con = getattr(self._local, "con", None)
        if con is None or getattr(self._local, "pid", None) != os.getpid():
            con = sqlite3.connect(str(self.path), timeout=BUSY_TIMEOUT_S, isolation_level=None)
            _enable_wal(con, BUSY_TIMEOUT_S)
            con.execute("PRAGMA synchronous=NORMAL")
            con.row_factory = sqlite3.Row
            self._local.con, self._local.pid = con, os.getpid()
            try:
                os.chmod(self.path, 0o600)
            except OSError:
                pass
        return con

    def _tx(self):
        return _Transaction(self._con())

    def close(self) -> None:
        """Close this thread's connection (a new one opens on the next call)."""
        con = getattr(self._local, "con", None)
        if con is not None and getattr(self._local, "pid", None) == os.getpid():
            con.close()
        self._local.con = None

    # ----- operations
    def submit(self, session: str, work_key: str | None = None, *, store: str = "", payload: bytes | None = None,
               cache_key: str | None = None) -> Submitted:
        """Queue a job for ``session`` (or share the queued/running job of ``store`` with
        the same ``work_key``: then ``payload`` is not stored and no process will start).
        ``payload`` is whatever the starter of :meth:`dispatch` needs; ``cache_key`` lets
        :meth:`waiter_for_cache_key` find the waiter again.

        A new job is refused when ``session`` already has ``queued_per_session`` queued
        jobs or the registry ``max_queued``: it is recorded as failed at once (no process
        will start) and :attr:`Submitted.refused` says why; sharing is never refused."""
        now = time.time()
        waiter = "w" + secrets.token_hex(12)
        refused = None
        with self._tx() as con:
            row = None
            if work_key:
                row = con.execute("SELECT id FROM jobs WHERE work_key = ? AND store = ? AND state IN (?, ?) "
                                  "ORDER BY seq LIMIT 1", (work_key, store, *ACTIVE)).fetchone()
            if row is not None:
                job, shared = row["id"], True
            else:
                job, shared = "j" + secrets.token_hex(12), False
                refused = self._queue_full(con, session)
                state = QUEUED if refused is None else FAILED
                con.execute("INSERT INTO jobs (id, work_key, session, store, state, created, finished, last_polled, "
                            "payload) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                            (job, None if refused else (work_key or None), session, store, state, now,
                             now if refused else None, now, None if refused else payload))
            con.execute("INSERT INTO waiters (id, job_id, cache_key, session, created, last_polled) "
                        "VALUES (?, ?, ?, ?, ?, ?)", (waiter, job, cache_key, session, now, now))
        return Submitted(job, waiter, shared, refused)

    def _queue_full(self, con, session: str) -> str | None:
        """Why a new job of ``session`` may not be queued now, None when it may."""
        mine = con.execute("SELECT COUNT(*) FROM jobs WHERE state = ? AND session = ?", (QUEUED, session)).fetchone()[0]
        if mine >= self.limits.queued_per_session:
            return (f"the server's queue is full: this session already has {mine} jobs waiting (at most "
                    f"{self.limits.queued_per_session}); try again later, when one of them has finished")
        total = con.execute("SELECT COUNT(*) FROM jobs WHERE state = ?", (QUEUED,)).fetchone()[0]
        if total >= self.limits.max_queued:
            return (f"the server's queue is full ({total} jobs waiting, at most {self.limits.max_queued}); "
                    f"try again later")
        return None

    def dispatch(self, start, *, store: str | None = None) -> list:
        """Start queued jobs (of ``store``, or any) while slots are free: oldest first, at
        most ``max_jobs`` running in total and ``per_session`` per session.

        ``start(job_id, payload) -> pid`` starts the process; its pid and creation time are
        recorded (see :meth:`record_start`). A job whose start raises is marked failed (and
        logged) and the other claimed jobs still start. Returns the started job ids."""
        now = time.time()
        claimed = []
        with self._tx() as con:
            running = con.execute("SELECT session, COUNT(*) AS n FROM jobs WHERE state = ? GROUP BY session",
                                  (RUNNING,)).fetchall()
            per_session = {r["session"]: r["n"] for r in running}
            free = self.limits.max_jobs - sum(per_session.values())
            if free <= 0:
                return []
            sql, args = "SELECT id, session, payload FROM jobs WHERE state = ?", [QUEUED]
            if store is not None:
                sql, args = sql + " AND store = ?", args + [store]
            for row in con.execute(sql + " ORDER BY seq", args).fetchall():
                if free <= 0:
                    break
                if per_session.get(row["session"], 0) >= self.limits.per_session:
                    continue
                con.execute("UPDATE jobs SET state = ?, owner = ?, started = ?, pid = NULL, payload = NULL "
                            "WHERE id = ?", (RUNNING, os.getpid(), now, row["id"]))
                per_session[row["session"]] = per_session.get(row["session"], 0) + 1
                free -= 1
                claimed.append((row["id"], row["payload"]))
        started = []
        for job, payload in claimed:
            try:
                pid = start(job, payload)
            except Exception as exc:  # noqa: BLE001 - one bad start must not strand the other claims
                LOGGER.warning("job %s did not start: %s", job, exc)
                try:
                    self.finish(job, ok=False)
                except sqlite3.Error as db_exc:  # reap marks it failed after START_GRACE_S
                    LOGGER.warning("job %s: %s", job, db_exc)
                continue
            if self.record_start(job, pid, process_ctime(pid)):
                started.append(job)
        return started

    def record_start(self, job_id: str, pid: int, ctime: float | None) -> bool:
        """Record the process of a claimed job (``ctime``: its creation time, None when it
        already ended). When the job is no longer running (cancelled or reaped between its
        claim and now), the new process is terminated at once with its process group and
        False is returned: no process runs uncounted."""
        with self._tx() as con:
            changed = con.execute("UPDATE jobs SET pid = ?, pid_ctime = ? WHERE id = ? AND state = ?",
                                  (int(pid), ctime, job_id, RUNNING)).rowcount
        if not changed:
            terminate_tree(pid, ctime)
        return bool(changed)

    def finish(self, job_id: str, ok: bool = True) -> None:
        """Mark a running job done (or failed); called by the job process at its end."""
        with self._tx() as con:
            con.execute("UPDATE jobs SET state = ?, finished = ? WHERE id = ? AND state = ?",
                        (DONE if ok else FAILED, time.time(), job_id, RUNNING))

    def heartbeat(self, waiter_id: str) -> None:
        """Record a poll of ``waiter_id`` (and of its job)."""
        now = time.time()
        with self._tx() as con:
            row = con.execute("SELECT job_id FROM waiters WHERE id = ?", (waiter_id,)).fetchone()
            if row is None:
                return
            con.execute("UPDATE waiters SET last_polled = ? WHERE id = ?", (now, waiter_id))
            con.execute("UPDATE jobs SET last_polled = ? WHERE id = ?", (now, row["job_id"]))

    def waiter(self, waiter_id: str) -> WaiterInfo | None:
        """The waiter ``waiter_id`` with its job's state, None when unknown."""
        row = self._con().execute(
            "SELECT w.id, w.job_id, w.detached, w.session, w.collected, j.state FROM waiters w "
            "JOIN jobs j ON j.id = w.job_id WHERE w.id = ?", (str(waiter_id),)).fetchone()
        return None if row is None else WaiterInfo(row["id"], row["job_id"], row["state"], bool(row["detached"]),
                                                   row["session"], bool(row["collected"]))

    def waiter_for_cache_key(self, cache_key: str) -> WaiterInfo | None:
        """The newest waiter submitted with ``cache_key``."""
        row = self._con().execute("SELECT id FROM waiters WHERE cache_key = ? ORDER BY created DESC LIMIT 1",
                                  (cache_key,)).fetchone()
        return None if row is None else self.waiter(row["id"])

    def job_state(self, job_id: str) -> str | None:
        row = self._con().execute("SELECT state FROM jobs WHERE id = ?", (job_id,)).fetchone()
        return None if row is None else row["state"]

    def job(self, job_id: str) -> dict | None:
        """The job row as a dict (without the payload), None when unknown."""
        row = self._con().execute("SELECT * FROM jobs WHERE id = ?", (job_id,)).fetchone()
        if row is None:
            return None
        out = dict(row)
        out.pop("payload", None)
        return out

    def queue_position(self, job_id: str) -> tuple[int, int] | None:
        """(queued jobs ahead of ``job_id``, running jobs) while it is queued, else None."""
        con = self._con()
        row = con.execute("SELECT seq, state FROM jobs WHERE id = ?", (job_id,)).fetchone()
        if row is None or row["state"] != QUEUED:
            return None
        ahead = con.execute("SELECT COUNT(*) FROM jobs WHERE state = ? AND seq < ?", (QUEUED, row["seq"])).fetchone()[0]
        return int(ahead), self.running_count()

    def collect(self, waiter_id: str) -> bool:
        """Record that ``waiter_id`` received its result; True when every waiter of the
        finished job has it (or left), so the result may be deleted."""
        with self._tx() as con:
            row = con.execute("SELECT job_id FROM waiters WHERE id = ?", (waiter_id,)).fetchone()
            if row is None:
                return False
            con.execute("UPDATE waiters SET collected = 1 WHERE id = ?", (waiter_id,))
            left = con.execute("SELECT COUNT(*) FROM waiters WHERE job_id = ? AND collected = 0 AND detached = 0",
                               (row["job_id"],)).fetchone()[0]
            state = con.execute("SELECT state FROM jobs WHERE id = ?", (row["job_id"],)).fetchone()
            return left == 0 and state is not None and state["state"] not in ACTIVE

    def cancel(self, waiter_id: str) -> bool:
        """Detach ``waiter_id``; cancel its job (terminate the process or drop it from the
        queue) only when no other waiter polled for it within the idle timeout. Returns
        True when the job was cancelled."""
        now = time.time()
        victim = None
        with self._tx() as con:
            row = con.execute("SELECT job_id FROM waiters WHERE id = ?", (str(waiter_id),)).fetchone()
            if row is None:
                return False
            job = row["job_id"]
            con.execute("UPDATE waiters SET detached = 1 WHERE id = ?", (str(waiter_id),))
            others = con.execute("SELECT COUNT(*) FROM waiters WHERE job_id = ? AND detached = 0 AND last_polled >= ?",
                                 (job, now - self.limits.idle_timeout_s)).fetchone()[0]
            j = con.execute("SELECT state, pid, pid_ctime FROM jobs WHERE id = ?", (job,)).fetchone()
            if others or j is None or j["state"] not in ACTIVE:
                return False
            con.execute("UPDATE jobs SET state = ?, finished = ?, payload = NULL WHERE id = ?", (CANCELLED, now, job))
            if j["state"] == RUNNING:
                victim = (j["pid"], j["pid_ctime"])
        if victim is not None:
            terminate_tree(*victim)
        return True

    def reap(self) -> ReapReport:
        """Cancel jobs no waiter polled for ``idle_timeout_s`` (queued ones are dropped,
        running ones terminated with their process group), mark as failed running jobs whose
        process ended without :meth:`finish` and claimed jobs without a recorded process
        after ``START_GRACE_S`` (or whose claiming server process has ended), and forget
        jobs finished over an hour ago."""
        now = time.time()
        idle, dropped, failed, victims = [], [], [], []
        with self._tx() as con:
            live = {r["job_id"] for r in con.execute(
                "SELECT DISTINCT job_id FROM waiters WHERE detached = 0 AND last_polled >= ?",
                (now - self.limits.idle_timeout_s,))}
            for j in con.execute("SELECT id, state, pid, pid_ctime, owner, started FROM jobs WHERE state IN (?, ?)",
                                 ACTIVE).fetchall():
                if j["id"] not in live:
                    con.execute("UPDATE jobs SET state = ?, finished = ?, payload = NULL WHERE id = ?",
                                (CANCELLED, now, j["id"]))
                    if j["state"] == RUNNING:
                        idle.append(j["id"])
                        victims.append((j["pid"], j["pid_ctime"]))
                    else:
                        dropped.append(j["id"])
                elif j["state"] == RUNNING:
                    if j["pid"] is None:
                        lost = (now - (j["started"] or now) > START_GRACE_S
                                or not process_alive(j["owner"], None))
                    else:
                        lost = not process_alive(j["pid"], j["pid_ctime"])
                    if lost:
                        con.execute("UPDATE jobs SET state = ?, finished = ? WHERE id = ? AND state = ?",
                                    (FAILED, now, j["id"], RUNNING))
                        failed.append(j["id"])
                        if j["pid"] is not None:
                            victims.append((j["pid"], j["pid_ctime"]))  # pool workers it may have left
            old = now - KEEP_FINISHED_S
            con.execute("DELETE FROM waiters WHERE job_id IN (SELECT id FROM jobs WHERE state NOT IN (?, ?) "
                        "AND finished < ?)", (*ACTIVE, old))
            con.execute("DELETE FROM jobs WHERE state NOT IN (?, ?) AND finished < ?", (*ACTIVE, old))
        for pid, ctime in victims:
            terminate_tree(pid, ctime)
        return ReapReport(tuple(idle), tuple(dropped), tuple(failed))

    def shutdown(self, owner: int | None = None) -> list:
        """Terminate every running job started by server process ``owner`` (default: this
        one) and mark it cancelled; for the server's exit. Returns the job ids."""
        owner = os.getpid() if owner is None else int(owner)
        now = time.time()
        with self._tx() as con:
            rows = con.execute("SELECT id, pid, pid_ctime FROM jobs WHERE state = ? AND owner = ?",
                               (RUNNING, owner)).fetchall()
            for r in rows:
                con.execute("UPDATE jobs SET state = ?, finished = ? WHERE id = ?", (CANCELLED, now, r["id"]))
        for r in rows:
            terminate_tree(r["pid"], r["pid_ctime"])
        return [r["id"] for r in rows]

    def running_count(self) -> int:
        """Jobs running now (on this machine, across server processes)."""
        return int(self._con().execute("SELECT COUNT(*) FROM jobs WHERE state = ?", (RUNNING,)).fetchone()[0])

    def session_running(self, session: str) -> int:
        """Jobs of ``session`` running now."""
        return int(self._con().execute("SELECT COUNT(*) FROM jobs WHERE state = ? AND session = ?",
                                       (RUNNING, session)).fetchone()[0])

    def queued_count(self) -> int:
        return int(self._con().execute("SELECT COUNT(*) FROM jobs WHERE state = ?", (QUEUED,)).fetchone()[0])

    def sweep_workers(self, cores: int | None = None) -> int:
        """Processes a sweep inside a running job should use: ``cores`` (default: usable
        cores) shared evenly among the running jobs, at least 1."""
        cores = usable_cores() if cores is None else max(1, int(cores))
        return max(1, cores // max(1, self.running_count()))


class _Transaction:
    """``BEGIN IMMEDIATE`` ... ``COMMIT`` (``ROLLBACK`` on error): the write lock is taken
    at the start, so a read-then-write decision cannot interleave with another process."""

    def __init__(self, con):
        self.con = con

    def __enter__(self):
        self.con.execute("BEGIN IMMEDIATE")
        return self.con

    def __exit__(self, exc_type, exc, tb):
        self.con.execute("ROLLBACK" if exc_type else "COMMIT")
        return False


def sweep_workers(cores: int | None = None) -> int:
    """:meth:`JobRegistry.sweep_workers` of the default registry; ``cores`` (default:
    usable cores) when the registry cannot be opened."""
    try:
        return JobRegistry().sweep_workers(cores)
    except (InputError, OSError, sqlite3.Error):
        return usable_cores() if cores is None else max(1, int(cores))


__all__ = ["MAX_JOBS_ENV", "PER_SESSION_ENV", "STATES", "TERM_GRACE_S", "Limits", "JobRegistry", "Submitted",
           "WaiterInfo", "ReapReport", "usable_cores", "process_alive", "process_ctime", "terminate_tree",
           "sweep_workers"]
