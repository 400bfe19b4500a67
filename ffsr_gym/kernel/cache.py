"""Keep numba's on-disk cache of the kernel consistent with the kernel's sources.

numba keys a cached function on its own file's timestamp only, but the kernel inlines code from
several modules of ``ffsr_gym.kernel``: after editing one of them (an editable install), the cached
closed loop would silently run the old code. On import we hash all kernel sources and, when the
hash differs from the one recorded next to the cache, flush every kernel function's cache.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from numba.core.registry import CPUDispatcher

from ffsr_gym.kernel import (
    batch,
    borrow,
    collision,
    decision,
    dynamics,
    field,
    flags,
    inverse,
    linalg,
    loop,
    physics,
    planner,
    score_terms,
    servo,
    settings,
    tumbling,
)

#: Modules with compiled functions (their caches are flushed together).
MODULES = (linalg, physics, dynamics, servo, collision, settings, field, inverse, planner, loop, score_terms, decision, batch,
           tumbling)
#: Everything compiled into those functions: the modules and the intrinsics they use.
SOURCES = (borrow, flags, *MODULES)


def sources_digest() -> str:
    """SHA-256 of the kernel modules' sources."""
    digest = hashlib.sha256()
    for module in SOURCES:
        digest.update(Path(module.__file__).read_bytes())
    return digest.hexdigest()


def refresh() -> None:
    """Flush the kernel's numba cache when the sources changed since it was written (its index files removed, so
    that :mod:`ffsr_gym.kernel.first_use` sees the next first calls compile)."""
    dispatchers = [obj for module in MODULES for obj in vars(module).values() if isinstance(obj, CPUDispatcher)]
    caches = [d._cache for d in dispatchers if getattr(d, "_cache", None) is not None and hasattr(d._cache, "flush")]
    if not caches:
        return
    stamp = Path(caches[0].cache_path) / "ffsr_gym_kernel.sha256"
    digest = sources_digest()
    try:
        if stamp.read_text() == digest:
            return
    except OSError:
        pass
    for cache in caches:
        cache.flush()
        index = getattr(getattr(cache, "_cache_file", None), "_index_path", None)
        if index is not None:  # no index at all, not an empty one: a first call then says it compiles (first_use)
            Path(index).unlink(missing_ok=True)
    try:
        stamp.write_text(digest)
    except OSError:
        pass  # read-only install: numba then caches elsewhere or not at all
