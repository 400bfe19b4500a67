"""Long studies on a Dask cluster: one way to name it, workers with pinned threads, and an executor the studies'
loops take.

``--scheduler ADDRESS`` names a running Dask scheduler (``tcp://host:8786``, or ``host:8786``); ``local:N`` starts a
``LocalCluster`` of N worker processes on this machine. Each worker runs one piece at a time, and every piece pins
the batched environments', torch's and the BLAS libraries' threads (one unless asked) before it runs, so it computes
the same numbers wherever it runs.
The studies send pure pieces (a chunk of candidates, one task's search) and the client writes what comes back,
atomically, as it arrives: a killed worker loses only the piece it was running (the scheduler runs it again on
another worker), and a killed client resumes from what it had written (docs/cluster.md).
"""

from __future__ import annotations

import os
import re
import sys
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import CancelledError, Executor, Future, InvalidStateError
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from ffsr_gym.exceptions import InvalidInputError, MissingDependencyError

_LOCAL = re.compile(r"local:([0-9]+)")
_ADDRESS = re.compile(r"(?:tcp://)?[A-Za-z0-9._-]+:[0-9]{1,5}")
#: The most workers ``local:N`` starts (one process each).
MAX_LOCAL_WORKERS = 256
#: How long the client waits for a scheduler to answer [s].
CONNECT_TIMEOUT_S = 20
#: How long a study waits with no worker on the cluster (none joined, or the last one left) before it stops [s].
NO_WORKER_TIMEOUT_S = 120.0
#: How often the client looks at the cluster's workers and scheduler while a study runs [s].
WATCH_INTERVAL_S = 2.0


@dataclass(frozen=True)
class Scheduler:
    """A parsed ``--scheduler``: a running scheduler's ``address``, or (``address`` None) a local cluster of
    ``workers`` processes."""

    address: str | None
    workers: int = 0


def parse_scheduler(text: str) -> Scheduler:
    """``local:N`` (1 <= N <= :data:`MAX_LOCAL_WORKERS`) or a scheduler's address (``tcp://host:port``, ``host:port``).

    Raises:
        InvalidInputError: anything else, naming the allowed forms.
    """
    allowed = f"allowed: local:N (N in [1, {MAX_LOCAL_WORKERS}] worker processes here) or a Dask scheduler's address " \
              "(tcp://host:8786 or host:8786)"
    if not isinstance(text, str):
        raise InvalidInputError(f"--scheduler {text!r}; {allowed}")
    if text.startswith("tls://"):
        raise InvalidInputError(f"--scheduler {text[:80]!r}: TLS needs certificates this command does not take; "
                                f"{allowed} (reach a TLS scheduler through an SSH tunnel to a tcp:// port)")
    local = _LOCAL.fullmatch(text)
    if local:
        workers = int(local.group(1))
        if not 1 <= workers <= MAX_LOCAL_WORKERS:
            raise InvalidInputError(f"--scheduler {text!r}; {allowed}")
        return Scheduler(None, workers)
    if _ADDRESS.fullmatch(text) and int(text.rsplit(":", 1)[1]) <= 65535:
        return Scheduler(text if "://" in text else f"tcp://{text}")
    raise InvalidInputError(f"--scheduler {text!r}; {allowed}")


def pin_threads(threads: int = 1) -> None:
    """Run the batched environments' copies, torch's and the BLAS libraries' code in this process on ``threads``
    threads (every cluster piece calls it first, :func:`pinned`; the environment variables reach the libraries
    loaded after it, and ``FFSR_GYM_THREADS`` the batched environments made after it)."""
    for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "FFSR_GYM_THREADS"):
        os.environ[name] = str(threads)
    try:
        import torch
    except ImportError:  # the RL extra is not installed: nothing to pin
        return
    torch.set_num_threads(threads)


def pinned(threads: int, function: Callable[..., Any], *args: Any) -> Any:
    """``function(*args)`` after :func:`pin_threads` in the thread that runs it."""
    pin_threads(threads)
    return function(*args)


def _bounded(call: Callable[[], Any], seconds: float) -> tuple[bool, Any]:
    """``(finished, result or exception)`` of ``call()`` run in a daemon thread, waited for at most ``seconds``: a
    network call that never returns (a port that accepts and says nothing) leaves the thread, not the study, waiting."""
    box: dict[str, Any] = {}

    def run() -> None:
        try:
            box["result"] = call()
        except BaseException as exc:  # noqa: BLE001 - whatever a foreign server provokes is reported by name
            box["error"] = exc

    thread = threading.Thread(target=run, daemon=True, name="ffsr-gym cluster call")
    thread.start()
    thread.join(seconds)
    if thread.is_alive():
        return False, None
    return True, box.get("error", box.get("result"))


def _connect(scheduler: str, target: Any) -> Any:
    """A Dask client of ``target`` (an address or a local cluster), or a named error within a bounded wait."""
    from distributed import Client

    finished, client = _bounded(lambda: Client(target, timeout=CONNECT_TIMEOUT_S), CONNECT_TIMEOUT_S + 10)
    if not finished:
        raise InvalidInputError(f"--scheduler {scheduler!r}: something accepts connections there but no Dask scheduler "
                                f"answered within {CONNECT_TIMEOUT_S + 10} s; check the address and port "
                                "(`dask scheduler` prints them)")
    if isinstance(client, BaseException):
        raise InvalidInputError(f"--scheduler {scheduler!r}: no Dask scheduler answered within {CONNECT_TIMEOUT_S} s "
                                f"({type(client).__name__}: {str(client)[:160]}); start one with `dask scheduler`, "
                                "or use local:N") from None
    return client


def _worker_threads(client: Any, seconds: float) -> int:
    """The threads of the cluster's workers now (0: no worker, or no answer from the scheduler within ``seconds``)."""
    finished, info = _bounded(lambda: client.scheduler_info(n_workers=-1), seconds)
    if not finished or not isinstance(info, dict):
        return 0
    return sum(worker["nthreads"] for worker in info.get("workers", {}).values())


class GuardedExecutor(Executor):
    """Calls on a cluster, each through :func:`pinned`, whose futures never wait forever: while they run, the client
    looks at the cluster every :data:`WATCH_INTERVAL_S`; once it has had no worker (none joined, or the last one
    left) or no scheduler for :data:`NO_WORKER_TIMEOUT_S`, every unfinished call fails with a named error, and a call
    the scheduler cancels (it was stopped or killed) fails with one too."""

    def __init__(self, client: Any, threads: int, scheduler: str) -> None:
        self.client, self.threads, self.scheduler = client, threads, scheduler
        self.inner = client.get_executor(pure=False)
        self._open: set[Future] = set()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._watch = threading.Thread(target=self._watch_loop, daemon=True, name="ffsr-gym cluster watch")
        self._watch.start()

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        """Run ``fn(*args)`` on the pool with the worker's threads pinned; keyword arguments are refused."""
        if kwargs:
            raise InvalidInputError("a cluster piece takes positional arguments only")
        outer: Future = Future()
        with self._lock:
            self._open.add(outer)
        self.inner.submit(pinned, self.threads, fn, *args).add_done_callback(lambda inner: self._settle(outer, inner))
        return outer

    def _settle(self, outer: Future, inner: Future) -> None:
        with self._lock:
            self._open.discard(outer)
        error = CancelledError() if inner.cancelled() else inner.exception()
        if isinstance(error, CancelledError):
            error = InvalidInputError(f"--scheduler {self.scheduler!r}: the scheduler cancelled a piece (it was "
                                      "stopped or killed, or the client lost it); run the command again: it resumes "
                                      "from what it had written")
        try:
            outer.set_exception(error) if error is not None else outer.set_result(inner.result())
        except InvalidStateError:  # already failed by the watch
            pass

    def _healthy(self) -> bool:
        return self.client.status == "running" and _worker_threads(self.client, 10.0) > 0

    def _watch_loop(self) -> None:
        unhealthy_since = None
        while not self._stop.wait(WATCH_INTERVAL_S):
            with self._lock:
                waiting = bool(self._open)
            if not waiting or self._healthy():
                unhealthy_since = None
                continue
            unhealthy_since = unhealthy_since or time.monotonic()
            if time.monotonic() - unhealthy_since >= NO_WORKER_TIMEOUT_S:
                self._fail_open()
                unhealthy_since = None

    def _fail_open(self) -> None:
        with self._lock:
            open_calls, self._open = list(self._open), set()
        for outer in open_calls:
            try:
                outer.set_exception(InvalidInputError(
                    f"--scheduler {self.scheduler!r}: no worker on the cluster, or no scheduler, for "
                    f"{NO_WORKER_TIMEOUT_S:.0f} s while {len(open_calls)} pieces waited; start workers with `dask "
                    "worker <scheduler address>` (or check the scheduler), then run the command again: it resumes"))
            except InvalidStateError:
                pass

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        self._stop.set()


@contextmanager
def cluster_executor(scheduler: str, *, threads: int = 1, say=print) -> Iterator[tuple[Executor, int]]:
    """``(executor, slots)`` on the cluster ``scheduler`` names (:func:`parse_scheduler`): a
    ``concurrent.futures.Executor`` whose calls run on its workers (:class:`GuardedExecutor`), and how many pieces run
    at once (the workers' threads). ``say`` gets the dashboard's address. The client, and a local cluster, close on
    exit. Every wait is bounded: the connection, the first worker (:data:`NO_WORKER_TIMEOUT_S`), and each call.

    Raises:
        InvalidInputError: a malformed ``scheduler``, no scheduler answering at its address (whatever else does), or
            no worker joining it (each named, with what to check).
        MissingDependencyError: Dask's ``distributed`` is not installed.
    """
    spec = parse_scheduler(scheduler)
    try:
        from distributed import LocalCluster
    except ImportError as exc:
        raise MissingDependencyError("--scheduler needs Dask: pip install 'ffsr-gym[dask]'") from exc
    cluster = None
    if spec.address is None:
        cluster = LocalCluster(n_workers=spec.workers, threads_per_worker=1, processes=True, dashboard_address=":0")
    try:
        client = _connect(scheduler, cluster if cluster is not None else spec.address)
        executor = None
        try:
            finished, _ = _bounded(lambda: client.wait_for_workers(1, timeout=NO_WORKER_TIMEOUT_S),
                                   NO_WORKER_TIMEOUT_S + 10)
            slots = _worker_threads(client, 30.0)
            if not finished or slots == 0:
                raise InvalidInputError(f"--scheduler {scheduler!r}: no worker joined the scheduler within "
                                        f"{NO_WORKER_TIMEOUT_S:.0f} s; start one with "
                                        f"`dask worker {spec.address or scheduler}`")
            if client.dashboard_link:
                say(f"Dask dashboard: {client.dashboard_link}")
            executor = GuardedExecutor(client, threads, scheduler)
            yield executor, max(1, slots)
        finally:
            if executor is not None:
                executor.shutdown()
            _bounded(client.close, 30.0)
    finally:
        if cluster is not None:
            cluster.close()


def machine_workers(asked: int, *, say: Callable[[str], Any] | None = None) -> int:
    """``asked`` worker processes, at most this machine's cores (one process per core is the most that helps; a
    hundred thousand would exhaust the machine before any work): a larger number is capped, and said so."""
    cores = os.cpu_count() or 1
    if asked <= cores:
        return asked
    (say or (lambda text: print(text, file=sys.stderr)))(f"--workers {asked:,}: capped at this machine's {cores} cores")
    return cores


@contextmanager
def study_executor(scheduler: str | None, local_workers: int = 1,
                   initializer: Callable[[], None] | None = None) -> Iterator[tuple[Executor | None, int]]:
    """``(executor, slots)`` of a long study: the cluster ``scheduler`` names (:func:`cluster_executor`), else
    ``local_workers`` processes of this machine started with ``initializer``, else (``(None, 1)``) this process
    alone."""
    if scheduler is not None:
        with cluster_executor(scheduler) as pair:
            yield pair
        return
    local_workers = machine_workers(local_workers)
    if local_workers <= 1:
        yield None, 1
        return
    from concurrent.futures import ProcessPoolExecutor

    executor = ProcessPoolExecutor(local_workers, initializer=initializer)
    try:
        yield executor, local_workers
    finally:
        executor.shutdown()
