"""A first use that compiles says so, with an estimate and the seconds spent; a quick one says nothing."""

from __future__ import annotations

import time

import pytest

from ffsr_gym.kernel import first_use


@pytest.fixture()
def fresh(monkeypatch):
    monkeypatch.setattr(first_use, "_done", set())
    monkeypatch.setattr(first_use, "QUIET_S", 0.2)
    monkeypatch.delenv(first_use.QUIET_ENV, raising=False)


def test_a_slow_first_call_is_announced_once_and_a_quick_one_never(fresh, capsys):
    assert first_use.call("batched env", lambda x: x + 1, 1) == 2  # quick: as a load from numba's cache
    assert capsys.readouterr().err == ""
    assert first_use.call("single env", lambda: time.sleep(1.5) or "done") == "done"  # slow: as a compilation
    err = capsys.readouterr().err
    assert "compiling the single env kernel" in err and "several times that on a busy or slower one" in err
    assert f"idle 2-core machine: {first_use.ESTIMATES_S['single env']:.0f} s" in err and "about" not in err  # no promise
    assert "compiled the single env kernel in" in err
    first_use.call("single env", time.sleep, 0.5)  # a later call of the same entry point
    assert capsys.readouterr().err == ""


def test_a_slow_first_call_of_a_function_numba_has_cached_is_work_not_compilation(fresh, capsys, tmp_path):
    from types import SimpleNamespace

    index = tmp_path / "decision.step_episode-1.py311.nbi"
    index.write_bytes(b"")

    def slow():
        time.sleep(0.6)

    slow._cache = SimpleNamespace(_cache_file=SimpleNamespace(_index_path=str(index)))  # as a numba dispatcher's
    first_use.call("single env", slow)
    assert capsys.readouterr().err == ""
    index.unlink()  # no index: the same slow first call is announced
    first_use._done.clear()
    first_use.call("single env", slow)
    assert "compiling the single env kernel" in capsys.readouterr().err


def test_an_error_in_the_first_call_reaches_the_caller_and_unknown_names_are_refused(fresh):
    with pytest.raises(ZeroDivisionError):
        first_use.call("closed loop", lambda: 1 / 0)
    with pytest.raises(KeyError, match="allowed"):
        first_use.call("double env", print)


def test_every_entry_point_the_package_announces_has_an_estimate():
    import re
    from pathlib import Path

    package = Path(first_use.__file__).resolve().parents[1]
    named = {name for path in package.rglob("*.py")
             for name in re.findall(r'first_use\.call\(\s*"([^"]+)"', path.read_text(encoding="utf-8"))}
    assert named == set(first_use.ESTIMATES_S)
