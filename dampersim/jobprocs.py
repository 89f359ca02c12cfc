"""Job processes: the cores a job may use, whether a recorded job process still runs, and
terminating it with everything it started.

A job process is recorded by its pid *and* its creation time, so that a pid the OS has
since given to an unrelated process is never signalled. Job processes call
:func:`os.setsid` first, so the job's pid is also the id of a process group holding its
pool workers; :func:`terminate_tree` ends that group as well.
"""

from __future__ import annotations

import os
import signal
import time

#: Seconds between SIGTERM and SIGKILL when a job is terminated.
TERM_GRACE_S = 0.5
#: Largest difference [s] between a recorded and a found creation time of the same process.
_CTIME_TOLERANCE_S = 0.05


def usable_cores() -> int:
    """Cores this process may run on (CPU affinity where the OS has it)."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)


def _process(pid, ctime):
    """The live process ``pid`` created at ``ctime`` (psutil), or None (ended, zombie, or
    the pid now belongs to another process)."""
    import psutil

    if not pid:
        return None
    try:
        proc = psutil.Process(int(pid))
        if ctime is not None and abs(proc.create_time() - float(ctime)) > _CTIME_TOLERANCE_S:
            return None
        if proc.status() == psutil.STATUS_ZOMBIE:
            return None
        return proc
    except (psutil.NoSuchProcess, psutil.AccessDenied, ProcessLookupError):
        return None


def process_alive(pid, ctime) -> bool:
    """Whether the process ``pid`` created at ``ctime`` [s since the epoch] still runs."""
    return _process(pid, ctime) is not None


def process_ctime(pid) -> float | None:
    """Creation time [s since the epoch] of process ``pid``, None when it has ended."""
    import psutil

    try:
        return psutil.Process(int(pid)).create_time()
    except (psutil.NoSuchProcess, psutil.AccessDenied):
        return None


def terminate_tree(pid, ctime, grace_s: float = TERM_GRACE_S) -> None:
    """Terminate job process ``pid`` (created at ``ctime``), its process group and its
    descendants: SIGTERM, then SIGKILL after ``grace_s`` seconds for what is left.

    Nothing is signalled when ``pid`` now belongs to another process (different creation
    time). The process group ``pid`` is signalled only when the job process still runs or
    no process holds that pid any more (a pid stays reserved while its group has members,
    so the group is then the job's remains)."""
    import psutil

    if not pid:
        return
    pid = int(pid)
    proc = _process(pid, ctime)
    try:
        holder = psutil.Process(pid)
    except psutil.NoSuchProcess:
        holder = None
    group_is_ours = proc is not None or holder is None or (
        ctime is not None and abs(holder.create_time() - float(ctime)) <= _CTIME_TOLERANCE_S)  # a zombie job
    targets = []
    if proc is not None:
        try:
            targets = [proc, *proc.children(recursive=True)]
        except psutil.NoSuchProcess:
            targets = [proc]
    if group_is_ours:
        for p in psutil.process_iter():
            try:
                if os.getpgid(p.pid) == pid and p not in targets:
                    targets.append(p)
            except (ProcessLookupError, PermissionError, psutil.NoSuchProcess):
                continue
    for sig in (signal.SIGTERM, signal.SIGKILL):
        if group_is_ours:
            try:
                os.killpg(pid, sig)
            except (ProcessLookupError, PermissionError):
                pass
        for p in targets:
            try:
                p.send_signal(sig)
            except (psutil.NoSuchProcess, psutil.AccessDenied):
                pass
        deadline = time.monotonic() + grace_s
        while time.monotonic() < deadline:
            if not any(_still_running(p) for p in targets):
                return
            time.sleep(0.02)


def _still_running(proc) -> bool:
    import psutil

    try:
        return proc.is_running() and proc.status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


__all__ = ["TERM_GRACE_S", "usable_cores", "process_alive", "process_ctime", "terminate_tree"]
