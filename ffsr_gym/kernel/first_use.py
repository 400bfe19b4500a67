"""Compile time you can see: the first call of each compiled entry point says so when it compiles.

numba compiles a kernel entry point on its first call with a new set of argument types, or loads it
from its on-disk cache in a second or two. A first call whose function has no index in that cache,
and that is still running after :data:`QUIET_S` seconds, is compiling: it prints what it compiles,
the time it took when measured (:data:`ESTIMATES_S`) and a bar of the seconds spent, on standard
error, and how long it took when done. Later calls in the process, and calls that load from the
cache, print nothing.

Plain Python: no compiled function lives here (the cache's source digest leaves it out).
"""

from __future__ import annotations

import os
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

#: Seconds a first call may take before it is announced (a load from numba's cache takes less).
QUIET_S = 3.0
#: What each first use compiled, in seconds, from an empty numba cache on 2 cores (x86_64), in the order a user
#: meets them, each after the one before it was cached (``benchmarks/setup_time.json``: the main job's first run
#: less its second, then each env's first use).
#: The servo plant runs in the same compiled functions (a flag of the settings): its first use compiles nothing.
ESTIMATES_S = {"closed loop": 120.0, "single env": 160.0, "batched env": 185.0, "target motion": 5.0}
#: Set to 1 to say nothing (tests that time calls, quiet scripts).
QUIET_ENV = "FFSR_GYM_QUIET_COMPILE"

_done: set[str] = set()


def call(what: str, function: Callable[..., Any], *args: Any) -> Any:
    """``function(*args)``, announced when it is the first call of ``what`` (a key of :data:`ESTIMATES_S`) in this
    process and it compiles."""
    if what in _done:
        return function(*args)
    if what not in ESTIMATES_S:
        raise KeyError(f"{what!r} is not a compiled entry point; allowed: {sorted(ESTIMATES_S)}")
    if _cached_on_disk(function):  # numba loads it: a long first call is work, not compilation
        _done.add(what)
        return function(*args)
    finished = threading.Event()
    watcher = threading.Thread(target=_watch, args=(what, finished), daemon=True, name=f"ffsr-gym compile: {what}")
    watcher.start()
    try:
        return function(*args)
    finally:
        finished.set()
        watcher.join()
        _done.add(what)


def _cached_on_disk(function: Any) -> bool:
    """Whether numba's on-disk cache has an index for ``function`` (then its first call loads it; the kernel's
    caches are flushed when a kernel source changes, :mod:`ffsr_gym.kernel.cache`). False for a plain function
    or a numba whose cache is laid out otherwise: the first call is then watched."""
    try:
        return Path(function._cache._cache_file._index_path).is_file()
    except (AttributeError, TypeError):
        return False


def _watch(what: str, finished: threading.Event) -> None:
    """Wait :data:`QUIET_S`; if the call still runs, show its compilation's progress until it returns."""
    start = time.perf_counter()
    if finished.wait(QUIET_S) or os.environ.get(QUIET_ENV) == "1":
        return
    estimate = ESTIMATES_S[what]
    sys.stderr.write(f"ffsr-gym: compiling the {what} kernel (its first use on this install; it took "
                     f"{_minutes(estimate)} on an idle 2-core machine, and can take several times that on a busy "
                     "or slower one); it is cached for later runs\n")
    from tqdm.auto import tqdm

    with tqdm(total=round(estimate), unit="s", desc=f"compiling the {what} kernel", file=sys.stderr, leave=False,
              bar_format=f"{{desc}}: {{bar}} {{n:.0f}} s (idle 2-core machine: {estimate:.0f} s)") as bar:
        while not finished.wait(1.0):
            bar.n = time.perf_counter() - start
            bar.total = max(bar.total, bar.n + 5)  # past the estimate the bar stays nearly full; the seconds go on
            bar.refresh()
    sys.stderr.write(f"ffsr-gym: compiled the {what} kernel in {time.perf_counter() - start:.0f} s\n")


def _minutes(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 90 else f"{seconds / 60:.0f} min"
