"""Where sweep points are computed: the worker task, the process pool and the Dask backend.

Processes: on Linux, from a process with no other Python thread, workers are forked: they
start at once with the parent's loaded kernel and code (about 1.5 s less per cold sweep on
2 cores than importing dampersim and loading the kernel in each new worker). Otherwise
(other threads, which a fork could copy in a locked state, or another OS) workers are
spawned and load numba's on-disk cache. Scripts that use spawned workers need the usual
``if __name__ == "__main__":`` guard.

Dask: a ``distributed`` scheduler at an address, or a local cluster on this machine. A
worker computes a point only when its package version, source hash and platform equal the
parent's (:func:`environment`), so that a result always matches the key it is stored under.

A Dask scheduler runs whatever task a client sends it (pickled functions), and ``tcp://``
neither encrypts nor authenticates: anyone on the network path could read the parameters,
inject results or run code on the workers. A ``tcp://`` (or scheme-less, or ``ws://``)
address is therefore accepted only on this machine (loopback); other machines are reached
through ``tls://`` with certificates (``distributed``'s ``Security``, configured in the Dask
config), or, knowingly, with ``DAMPERSIM_ALLOW_INSECURE_DASK=1``
(:func:`check_scheduler_address`).
"""

from __future__ import annotations

import ipaddress
import multiprocessing
import os
import signal
import sys
import threading
import time
import traceback
from concurrent import futures as cf

from dampersim import keys
from dampersim.errors import DampersimError, InputError
from dampersim.simulation import ensure_compiled
from dampersim.sweeps import cache as _cache
from dampersim.version import __version__

#: Environment variable with the address of a Dask scheduler (e.g. tcp://host:8786).
SCHEDULER_ENV = "DAMPERSIM_SCHEDULER"
#: Environment variable that, set to 1, allows an unencrypted scheduler on another machine.
ALLOW_INSECURE_DASK_ENV = "DAMPERSIM_ALLOW_INSECURE_DASK"
#: Address schemes that neither encrypt nor authenticate.
INSECURE_SCHEMES = ("tcp", "ws")
#: Host names that always mean this machine.
LOOPBACK_NAMES = ("localhost", "localhost.localdomain", "ip6-localhost")
#: Seconds allowed to connect to a Dask scheduler.
CONNECT_TIMEOUT = 5.0
#: Seconds to wait for a reachable scheduler that has no workers yet.
WORKER_WAIT = 30.0


# --------------------------------------------------------------------------- address check
def _is_loopback(host: str) -> bool:
    host = host.strip().strip("[]").lower()
    if host in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _address_host(rest: str) -> str:
    """Host part of ``host:port``, ``[v6]:port`` or ``host``."""
    rest = rest.split("/", 1)[0]
    if rest.startswith("["):
        return rest[1:].split("]", 1)[0]
    if rest.count(":") > 1:  # bare IPv6 without brackets
        return rest
    return rest.rsplit(":", 1)[0] if ":" in rest else rest


def check_scheduler_address(address: str) -> str:
    """Refuse an unencrypted scheduler address on another machine (see the module
    docstring); returns ``address``. ``tls://`` addresses, ``inproc://`` and loopback
    ``tcp://`` are accepted; ``$DAMPERSIM_ALLOW_INSECURE_DASK=1`` accepts any."""
    if not isinstance(address, str) or not address.strip():
        raise InputError(f"scheduler = {address!r}: accepted is an address such as tls://host:8786")
    text = address.strip()
    scheme, sep, rest = text.partition("://")
    if not sep:
        scheme, rest = "tcp", text  # distributed's default protocol
    scheme = scheme.lower()
    if scheme not in INSECURE_SCHEMES or _is_loopback(_address_host(rest)):
        return address
    if os.environ.get(ALLOW_INSECURE_DASK_ENV, "").strip() == "1":
        return address
    raise InputError(
        f"scheduler = {address!r}: an unencrypted {scheme}:// connection to another machine is refused "
        f"(anyone on the network could read or alter the work, or run code on the workers); accepted are "
        f"tls://HOST:PORT with certificates, {scheme}:// on this machine (127.0.0.1, localhost, ::1), or "
        f"{ALLOW_INSECURE_DASK_ENV}=1 to allow it on a trusted network"
    )


# --------------------------------------------------------------------------- worker side
def environment(source: str | None = None) -> tuple:
    """What a worker must share with the parent for its result to match the key: the
    package version, the source hash (``source``: the parent's pinned one; default this
    process's) and the platform (library versions, CPU target)."""
    return (__version__, _cache.kernel_source_hash() if source is None else source, keys.digest(keys.platform()))


def compute_task(system, point, duration, window, key, expected_env):
    """Compute one point; runs in a worker. Never raises: returns ("ok", record bytes),
    ("mismatch", worker environment) or ("error", type name, message) so that no
    exception has to survive pickling between processes."""
    try:
        env = environment()
        if tuple(env) != tuple(expected_env):
            return ("mismatch", env)
        record = _cache.compute_record(system, point, duration=duration, window=window, key=key)
        return ("ok", record.to_bytes())
    except DampersimError as exc:
        return ("error", type(exc).__name__, str(exc))
    except Exception as exc:  # report, do not lose, unexpected failures
        return ("error", type(exc).__name__, f"{exc}\n{traceback.format_exc()}")


def _pool_initializer():
    # Ctrl-C goes to the whole process group: let the parent decide (it cancels cleanly).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        ensure_compiled()
    except Exception:  # the first task will report the problem with context
        pass


def _start_method() -> str:
    """"fork" where it is safe and available (see the module docstring), else "spawn"."""
    if sys.platform.startswith("linux") and threading.active_count() == 1:
        return "fork"
    return "spawn"


def process_pool(workers: int) -> cf.ProcessPoolExecutor:
    """A pool of ``workers`` processes for kernel work, started as the module docstring
    describes (fork where safe, else spawn). The kernel is loaded in this process first,
    so forked workers inherit it and spawned ones only read numba's disk cache."""
    ensure_compiled()
    ctx = multiprocessing.get_context(_start_method())
    return cf.ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_pool_initializer)


# --------------------------------------------------------------------------- backends
class PoolBackend:
    """Sweep points on a local process pool."""

    name = "processes"

    def __init__(self, workers):
        self.pool = process_pool(workers)
        # one task queued behind each running one: a worker that finishes starts its next
        # point at once instead of waiting for this process to store the result and
        # submit; a queued task is still cancellable (Future.cancel) when the sweep stops
        self.slots = 2 * workers

    def submit(self, *args):
        return self.pool.submit(compute_task, *args)

    def wait(self, fs, timeout):
        done, _ = cf.wait(list(fs), timeout=timeout, return_when=cf.FIRST_COMPLETED)
        return done

    def cancel(self, fut) -> bool:
        return fut.cancel()

    def result(self, fut):
        return fut.result()

    def close(self, abort=False):
        self.pool.shutdown(wait=not abort, cancel_futures=True)


class DaskBackend:
    """Sweep points on a Dask distributed scheduler (or a local Dask cluster)."""

    name = "dask"

    def __init__(self, address, workers):
        if address is not None:
            check_scheduler_address(address)
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise InputError(
                "executor 'dask' needs dask[distributed]; install it with "
                "pip install 'dampersim[dask]'"
            ) from None
        self.cluster = None
        if address is None:
            n = workers or cpu_count()
            self.cluster = LocalCluster(
                n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                dashboard_address=None,
            )
            address = self.cluster.scheduler_address
        self.address = address
        try:
            self.client = Client(address, timeout=CONNECT_TIMEOUT, set_as_default=False)
        except Exception as exc:
            self._close_cluster()
            raise InputError(
                f"cannot reach the Dask scheduler at {address!r} within {CONNECT_TIMEOUT:g} s "
                f"({type(exc).__name__}: {exc}); start one (e.g. `dask scheduler` and "
                f"`dask worker ADDRESS`) or pass another address with --scheduler / "
                f"{SCHEDULER_ENV}"
            ) from None
        try:
            nthreads = sum(self.client.nthreads().values())
            if nthreads == 0:
                self.client.wait_for_workers(1, timeout=WORKER_WAIT)
                nthreads = sum(self.client.nthreads().values())
        except Exception:
            self.close(abort=True)
            raise InputError(
                f"the Dask scheduler at {address!r} has no workers (waited {WORKER_WAIT:g} s); "
                "start workers with `dask worker ADDRESS`"
            ) from None
        self.slots = max(1, nthreads)

    def submit(self, *args):
        return self.client.submit(compute_task, *args, pure=False)

    def wait(self, fs, timeout):
        deadline = time.monotonic() + timeout
        while True:
            done = {f for f in fs if f.done()}
            if done or time.monotonic() >= deadline:
                return done
            time.sleep(0.02)

    def cancel(self, fut) -> bool:
        return False  # every submitted task is running (in-flight <= worker threads): let it finish

    def result(self, fut):
        return fut.result()

    def _close_cluster(self):
        if self.cluster is not None:
            try:
                self.cluster.close()
            except Exception:
                pass
            self.cluster = None

    def close(self, abort=False):
        try:
            self.client.close()
        except Exception:
            pass
        self._close_cluster()


def cpu_count() -> int:
    """Cores this process may use (its CPU affinity where the OS tells it)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)
