"""Long studies on a Dask cluster: one way to name it, workers with pinned threads, and an executor the studies'
loops take.

``--scheduler ADDRESS`` names a running Dask scheduler (``tcp://host:8786``, or ``host:8786``); ``local:N`` starts a
``LocalCluster`` of N worker processes on this machine. Each worker runs one piece at a time, and every piece pins
numba's, torch's and the BLAS libraries' threads (one unless asked) before it runs, so it computes the same numbers
wherever it runs.
The studies send pure pieces (a chunk of candidates, one task's search) and the client writes what comes back,
atomically, as it arrives: a killed worker loses only the piece it was running (the scheduler runs it again on
another worker), and a killed client resumes from what it had written (docs/cluster.md).
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Iterator
from concurrent.futures import Executor, Future
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from ffsr_gym.exceptions import InvalidInputError, MissingDependencyError

_LOCAL = re.compile(r"local:([0-9]+)")
_ADDRESS = re.compile(r"(?:(?:tcp|tls)://)?[A-Za-z0-9._-]+:[0-9]{1,5}")
#: The most workers ``local:N`` starts (one process each).
MAX_LOCAL_WORKERS = 256
#: How long the client waits for a scheduler to answer [s].
CONNECT_TIMEOUT_S = 20


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
    """Run numba's code in the calling thread, and torch's and the BLAS libraries' in this process, on ``threads``
    threads (every cluster piece calls it first, :func:`pinned`; the environment variables reach the libraries
    loaded after it)."""
    for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[name] = str(threads)
    import numba

    numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    try:
        import torch
    except ImportError:  # the RL extra is not installed: nothing to pin
        return
    torch.set_num_threads(threads)


def pinned(threads: int, function: Callable[..., Any], *args: Any) -> Any:
    """``function(*args)`` after :func:`pin_threads` in the thread that runs it (numba's setting is per thread)."""
    pin_threads(threads)
    return function(*args)


class PinnedExecutor(Executor):
    """An executor that runs every call of another one through :func:`pinned` (``map`` comes from ``submit``)."""

    def __init__(self, inner: Executor, threads: int) -> None:
        self.inner, self.threads = inner, threads

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        if kwargs:
            raise InvalidInputError("a cluster piece takes positional arguments only")
        return self.inner.submit(pinned, self.threads, fn, *args)

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        self.inner.shutdown(wait=wait)


@contextmanager
def cluster_executor(scheduler: str, *, threads: int = 1, say=print) -> Iterator[tuple[Executor, int]]:
    """``(executor, slots)`` on the cluster ``scheduler`` names (:func:`parse_scheduler`): a
    ``concurrent.futures.Executor`` whose calls run on its workers, and how many pieces run at once (the workers'
    threads). ``say`` gets the dashboard's address. The client, and a local cluster, close on exit.

    Raises:
        InvalidInputError: a malformed ``scheduler``, or no scheduler answering at its address.
        MissingDependencyError: Dask's ``distributed`` is not installed.
    """
    spec = parse_scheduler(scheduler)
    try:
        from distributed import Client, LocalCluster
    except ImportError as exc:
        raise MissingDependencyError("--scheduler needs Dask: pip install 'ffsr-gym[dask]'") from exc
    cluster = None
    if spec.address is None:
        cluster = LocalCluster(n_workers=spec.workers, threads_per_worker=1, processes=True, dashboard_address=":0")
    try:
        try:
            client = Client(cluster if cluster is not None else spec.address, timeout=CONNECT_TIMEOUT_S)
        except OSError as exc:
            raise InvalidInputError(f"--scheduler {scheduler!r}: no Dask scheduler answered within "
                                    f"{CONNECT_TIMEOUT_S} s ({type(exc).__name__}); start one with `dask scheduler`, "
                                    "or use local:N") from None
        try:
            slots = sum(w["nthreads"] for w in client.scheduler_info()["workers"].values())
            if client.dashboard_link:
                say(f"Dask dashboard: {client.dashboard_link}")
            yield PinnedExecutor(client.get_executor(pure=False), threads), max(1, slots)
        finally:
            client.close()
    finally:
        if cluster is not None:
            cluster.close()


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
    if local_workers <= 1:
        yield None, 1
        return
    from concurrent.futures import ProcessPoolExecutor

    executor = ProcessPoolExecutor(local_workers, initializer=initializer)
    try:
        yield executor, local_workers
    finally:
        executor.shutdown()
