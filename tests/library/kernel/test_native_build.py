"""The installed native kernel was built from this checkout's sources: the digest compiled into it
(``ffsr_gym._native.SOURCE_SHA256``, CMakeLists.txt) equals one computed here from the files. A stale build (an
editable install not rebuilt after an edit of ``src/native``) fails here instead of running old code."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

from ffsr_gym import _native

ROOT = Path(__file__).resolve().parents[3]


def test_the_extension_was_built_from_these_sources():
    native = ROOT / "src" / "native"
    if not native.is_dir():
        pytest.skip("not a checkout: the sources are not here")
    names = sorted(path.relative_to(ROOT).as_posix() for path in native.rglob("*") if path.is_file())
    text = "".join(f"{name}\n{hashlib.sha256((ROOT / name).read_bytes()).hexdigest()}\n"
                   for name in [*names, "CMakeLists.txt"])
    assert _native.SOURCE_SHA256 == hashlib.sha256(text.encode()).hexdigest(), (
        "the installed ffsr_gym._native is not built from src/native as it is: pip install -e . (or .) again")
