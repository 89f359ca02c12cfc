"""Load runs against a real dashboard server: many sessions open links that start sweeps
while a probe measures how fast a light page request is answered.

Used by the hardening tier (16 sessions, assertions) and by ``bench/bench_load.py`` (4, 16
and 64 sessions, figures). The server runs in its own process on loopback with its own
cache folder; everything here stops by itself (fixed session count, deadlines).
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import psutil

from tests.hardening.dashclient import DashSession

ROOT = Path(__file__).resolve().parents[2]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_server(cache_dir, *args, port=None, env=None, ready_s=180.0):
    """Start ``python app.py`` on loopback; returns (process, base URL) once it answers."""
    port = port or free_port()
    environ = {**os.environ, "DAMPERSIM_CACHE_DIR": str(cache_dir), **(env or {})}
    environ.setdefault("NUMBA_CACHE_DIR", str(ROOT / ".numba-cache"))
    log = open(Path(cache_dir).parent / f"server-{port}.log", "wb")
    proc = subprocess.Popen([sys.executable, str(ROOT / "app.py"), "--host", "127.0.0.1", "--port", str(port), *args],
                            cwd=str(ROOT), env=environ, stdout=log, stderr=subprocess.STDOUT)
    base = f"http://127.0.0.1:{port}"
    t0 = time.monotonic()
    while time.monotonic() - t0 < ready_s:
        if proc.poll() is not None:
            raise RuntimeError(f"the server exited with {proc.returncode}; see {log.name}")
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=0.5):
                pass
            if DashSession(base, timeout=5).request("/_dash-dependencies").status == 200:
                return proc, base
        except OSError:
            pass
        time.sleep(0.3)
    proc.kill()
    raise RuntimeError("the server did not answer in time")


def stop_server(proc, timeout=20.0, seen=()) -> list:
    """SIGTERM the server, wait; returns the pids of its descendants still alive after it
    stopped (orphans), killing them so a failed test leaves nothing behind.

    The descendants checked are the server's process tree as it is when the stop begins
    plus ``seen`` (psutil processes recorded earlier, e.g. :attr:`Monitor.seen` while jobs
    were running), so a job process that left the tree (its parent gone, re-parented to
    init) still counts. psutil matches a pid with its start time, so a reused pid is not
    taken for an orphan."""
    try:
        kids = psutil.Process(proc.pid).children(recursive=True)
    except psutil.NoSuchProcess:
        kids = []
    known = {k.pid for k in kids}
    kids += [k for k in seen if k.pid not in known and k.pid != proc.pid]
    proc.terminate()
    try:
        proc.wait(timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(5)
    time.sleep(0.5)
    alive = []
    for k in kids:
        try:
            if k.is_running() and k.status() != psutil.STATUS_ZOMBIE:
                alive.append(k)
        except psutil.NoSuchProcess:
            pass
    for k in alive:
        try:
            k.kill()
        except psutil.NoSuchProcess:
            pass
    return [k.pid for k in alive]


def sweep_link(i: int, points: int = 6, duration: float = 8.0) -> str:
    """A colourmap link whose sweep takes a few seconds (``points`` speeds of ``duration``
    [s] each); links with the same ``i`` are identical requests."""
    start = 1000 + 40 * i
    speeds = ",".join(str(start + 7 * k) for k in range(points))
    return f"/colourmap?speeds={speeds}&torque=150&orders=2:200&duration={duration:g}&window=0.6"


class Monitor(threading.Thread):
    """Samples the server's process tree every ``period`` s: job processes (descendants
    that lead their own session), all processes of the tree and their summed RSS [B]."""

    def __init__(self, pid: int, period: float = 0.1):
        super().__init__(daemon=True)
        self.pid, self.period = pid, period
        self.max_jobs = 0
        self.max_procs = 0
        self.max_rss = 0
        self.job_pids = set()
        #: every process of the tree seen so far, by pid (for :func:`stop_server`)
        self.seen = {}
        self.jobs_now = 0
        self.stop_flag = threading.Event()

    def run(self):
        try:
            server = psutil.Process(self.pid)
        except psutil.NoSuchProcess:
            return
        while not self.stop_flag.is_set():
            try:
                tree = [server, *server.children(recursive=True)]
                # a job process leads its own session (it calls setsid), so its pool
                # workers and the fork server that started it are not counted as jobs
                jobs = []
                for p in tree[1:]:
                    try:
                        if p.status() != psutil.STATUS_ZOMBIE and os.getsid(p.pid) == p.pid:
                            jobs.append(p)
                    except (OSError, psutil.Error):
                        pass
                rss = 0
                for p in tree:
                    try:
                        rss += p.memory_info().rss
                    except psutil.NoSuchProcess:
                        pass
                for p in tree[1:]:
                    self.seen.setdefault(p.pid, p)
                self.jobs_now = len(jobs)
                self.max_jobs = max(self.max_jobs, len(jobs))
                self.job_pids.update(p.pid for p in jobs)
                self.max_procs = max(self.max_procs, len(tree))
                self.max_rss = max(self.max_rss, rss)
            except psutil.NoSuchProcess:
                return
            except psutil.Error:
                pass
            time.sleep(self.period)


def _percentile(values, q):
    if not values:
        return float("nan")
    s = sorted(values)
    return s[min(len(s) - 1, int(round(q * (len(s) - 1))))]


#: The page the probe loads as the light page request.
PROBE_PAGE = "/explorer?speed=1500&torque=200"


def load_page(s: DashSession, link: str = PROBE_PAGE) -> float:
    """Load ``link`` as a browser does (the page's HTML, then the ``_pages_content``
    callback that returns its layout, :meth:`DashSession.open`; the layout and
    dependencies of the app once per session); returns the seconds it took, or raises
    when a step failed."""
    t0 = time.perf_counter()
    out = s.open(link)
    seconds = time.perf_counter() - t0
    if out.status != 200 or not s.layout:
        raise RuntimeError(f"loading {link} answered {out.status}: {out.text[:200]}")
    return seconds


def start_sweeps(base: str, sessions: int, distinct: int, points: int, duration: float, deadline_s: float,
                 results: dict) -> list:
    """Threads (started) in which ``sessions`` sessions open ``distinct`` sweep links and
    poll their jobs until they answer or ``deadline_s``; outcomes go to ``results``."""

    def session(i):
        s = DashSession(base, timeout=60)
        link = sweep_link(i % distinct, points, duration)
        try:
            s.open(link)
            page = link.split("?")[0].strip("/")
            r = s.call_outputs(f"{page}-job.data")
            job = ((r.json or {}).get("response", {}).get(f"{page}-job") or {}).get("data")
            if job is None:
                results[i] = ("no-job", r.status, r.text[:300])
                return
            final, polls = s.run_background(f"{page}-done.data", {f"{page}-job.data": job}, deadline_s=deadline_s)
            results[i] = ("ok" if final.status == 200 and "error" not in final.text[:500] else "bad", final.status,
                          final.text[:300])
        except Exception as exc:  # recorded, the run goes on
            results[i] = ("exception", 0, repr(exc))

    threads = [threading.Thread(target=session, args=(i,), daemon=True) for i in range(sessions)]
    for t in threads:
        t.start()
    return threads


def run_load(base: str, server_pid: int, sessions: int, distinct: int = 4, deadline_s: float = 300.0,
             points: int = 6, duration: float = 8.0) -> dict:
    """``sessions`` sessions open ``distinct`` different sweep links (round robin) at once;
    a probe loads a page (:func:`load_page`, :data:`PROBE_PAGE`: a light page request)
    every 0.1 s meanwhile.

    Returns a dict: latency_p50_s, latency_p95_s (probe), probe_count, probe_errors, max_jobs,
    jobs_started (distinct job processes seen), max_processes, peak_rss_mb (server tree), finished (sessions whose sweep answered),
    failed (list of (session, status, text)), wall_s, seen (every process of the server's
    tree seen, for :func:`stop_server`).
    """
    monitor = Monitor(server_pid)
    monitor.start()
    latencies, errors, stop = [], [], threading.Event()

    def probe():
        s = DashSession(base, timeout=30)
        while not stop.is_set():
            try:
                latencies.append(load_page(s))
            except Exception as exc:  # counted, the probe goes on
                errors.append(repr(exc)[:200])
            time.sleep(0.1)

    results = {}
    t0 = time.perf_counter()
    prober = threading.Thread(target=probe, daemon=True)
    prober.start()
    threads = start_sweeps(base, sessions, distinct, points, duration, deadline_s, results)
    for t in threads:
        t.join(deadline_s)
    wall = time.perf_counter() - t0
    stop.set()
    prober.join(5)
    monitor.stop_flag.set()
    monitor.join(5)
    failed = [(i, st, text) for i, (kind, st, text) in sorted(results.items()) if kind != "ok"]
    return {
        "sessions": sessions,
        "latency_p50_s": _percentile(latencies, 0.5),
        "latency_p95_s": _percentile(latencies, 0.95),
        "probe_count": len(latencies),
        "probe_errors": errors,
        "max_jobs": monitor.max_jobs,
        "jobs_started": len(monitor.job_pids),
        "max_processes": monitor.max_procs,
        "peak_rss_mb": monitor.max_rss / 2**20,
        "finished": sum(1 for kind, _, _ in results.values() if kind == "ok"),
        "failed": failed,
        "wall_s": wall,
        "seen": list(monitor.seen.values()),
    }


__all__ = ["free_port", "start_server", "stop_server", "sweep_link", "Monitor", "PROBE_PAGE", "load_page", "start_sweeps",
           "run_load"]
