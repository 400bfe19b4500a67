"""Provenance of every number that leaves the repository, and atomic result files."""

from __future__ import annotations

import glob
import json
import os
import platform
import subprocess
import sys
import tempfile
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path
from typing import Any

from ffsr_gym.exceptions import FFSRError, WriteError

#: mujoco runs the speed benchmark's reference (Pusher-v5), when installed.
_PACKAGES = ("ffsr-gym", "numpy", "pin", "coal", "gymnasium", "matplotlib", "stable-baselines3", "torch",
             "mujoco", "cma", "optuna", "rliable", "minari")
_SOURCE = Path(__file__).resolve().parent.parent


def _git(*args: str, cwd: Path = _SOURCE) -> str | None:
    try:
        out = subprocess.run(["git", *args], cwd=cwd, capture_output=True, text=True, timeout=10, check=True)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip()


def package_versions() -> dict[str, str]:
    """Installed versions of the packages that shape results (absent ones are skipped)."""
    versions = {"python": platform.python_version()}
    for name in _PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return versions


def _git_tree() -> tuple[Path | None, str]:
    """The git work tree whose commit describes this run, and a note on where it comes from.

    The package's own checkout (editable install or source tree) first; else the working
    directory's tree (a wheel installed into a project that is under git); else none.
    """
    if (_SOURCE / ".git").exists():
        return _SOURCE, "the ffsr-gym checkout"
    top = _git("rev-parse", "--show-toplevel", cwd=Path.cwd())
    if top:
        return Path(top), f"the working directory's repository {top} (ffsr-gym is installed, not a checkout)"
    return None, f"not a git checkout: ffsr-gym {_version()} installed from a wheel or sdist, run outside any git tree"


def is_source_checkout() -> bool:
    """Whether this package runs from its own git checkout (not from an installed wheel or sdist)."""
    return (_SOURCE / ".git").exists()


def is_checkout_commit(commit: str) -> bool | None:
    """Whether ``commit`` is a commit of the ffsr-gym checkout this package runs from; None when that cannot be told
    (an installed wheel, no git, or a shallow clone, whose history is partial)."""
    if not is_source_checkout() or _git("rev-parse", "--is-shallow-repository") != "false":
        return None
    return _git("cat-file", "-e", f"{commit}^{{commit}}") is not None


def source_commit() -> str | None:
    """The commit of the ffsr-gym checkout this package runs from, or None (an installed wheel or sdist)."""
    return _git("rev-parse", "HEAD", cwd=_SOURCE) if is_source_checkout() else None


def git_config(key: str) -> str | None:
    """A value of the user's git configuration (``user.name``, ...), or None (no git, or not set)."""
    return _git("config", "--get", key, cwd=Path.cwd()) or None


def _version() -> str:
    try:
        return metadata.version("ffsr-gym")
    except metadata.PackageNotFoundError:
        return "unknown"


#: The ``envs`` files the lab keeps in the checkout and the library's wheel leaves out (CMakeLists.txt's install
#: rule names the same pattern: CMake reads no Python).
LAB_DATA = "*_best_known*.json"


def checkout_state() -> tuple[str | None, bool | None, str]:
    """(commit, dirty, where the tree comes from) of the git work tree that describes this run (commit and dirty
    None outside a checkout). Generated results (leaderboard entries and tables, the long studies' records, the best
    known scores) and what no run executes (the docs, the tests, Markdown pages) do not make the code dirty."""
    tree, source = _git_tree()
    commit = None if tree is None else _git("rev-parse", "HEAD", cwd=tree)
    dirty = None if commit is None else bool(_git("status", "--porcelain", "--untracked-files=no", "--", ".",
                                                 ":(exclude)leaderboards", ":(exclude)studies",
                                                 f":(exclude)envs/benchmark/{LAB_DATA}", ":(exclude)docs",
                                                 ":(exclude)tests", ":(exclude)*.md", cwd=tree))
    return commit, dirty, source


def provenance(*, scenarios: dict[str, str] | None = None, seeds: list[int] | None = None,
               command: str | None = None, wall_time_s: float | None = None) -> dict[str, Any]:
    """Describe where a result comes from.

    Args:
        scenarios: scenario name → sha256 (content and robot files).
        seeds: the random seeds used, if any.
        command: the command line; default: this process's ``sys.argv``.
        wall_time_s: wall-clock time of the run [s].

    Returns:
        A JSON-ready dict: git commit and dirty flag (None outside a git checkout), package
        versions, platform, command, seeds, scenario hashes, wall time and a UTC timestamp.
    """
    commit, dirty, source = checkout_state()
    return {
        "git_commit": commit,
        "git_dirty": dirty,
        "git_source": source,
        "versions": package_versions(),
        "platform": f"{platform.platform()} ({platform.machine()}, {os.cpu_count()} CPUs)",
        "cpu": cpu_description(),
        "command": command if command is not None else " ".join([Path(sys.argv[0]).name, *sys.argv[1:]]),
        "seeds": seeds,
        "scenario_sha256": scenarios or {},
        "wall_time_s": wall_time_s,
        "created_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }


def cpu_description() -> str:
    """The CPU model, the SIMD flags that decide the last bits of numbers (FMA, AVX2, AVX-512: glibc's libm and
    OpenBLAS choose their code by them; docs/model.md §17) and the C library's version."""
    try:
        lines = Path("/proc/cpuinfo").read_text(encoding="utf-8").splitlines()
    except OSError:
        lines = []
    model = next((line.split(":", 1)[1].strip() for line in lines if line.startswith("model name")), "")
    flags = next((line.split(":", 1)[1].split() for line in lines if line.startswith("flags")), [])
    simd = sorted(f for f in flags if f in ("fma", "avx", "avx2") or f.startswith("avx512"))
    libc = " ".join(part for part in platform.libc_ver() if part)
    return f"{platform.machine()} {model or platform.processor()} ({' '.join(simd) or 'no FMA/AVX flags'}), {libc}"


def _current_umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_text_atomic(path: str | Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and an atomic rename.

    The file keeps the user's umask (not mkstemp's 0600). The temporary's name carries the
    writer's process id (``.<name>.<pid>.<random>.tmp``): a writer killed mid-write leaves the
    previous file intact and its temporary, which the next write of ``path`` removes once that
    process is gone; a live writer's temporary is never touched, so concurrent writers of one file
    each land whole (the last rename wins).

    Raises:
        WriteError: the file cannot be written (a full disk, no permission), naming it.
    """
    _write_named(Path(path), text)


#: Set to 1, a leaderboard table takes entries of a checkout with uncommitted code changes without being asked each
#: time (``EvalReport.save(allow_dirty=None)``; the test suite sets it: a developer's tree is dirty by nature).
ALLOW_DIRTY_VARIABLE = "FFSR_GYM_ALLOW_DIRTY"


def dirty_allowed(flag: bool | None) -> bool:
    """Whether a dirty checkout's entry may go into a leaderboard table: ``flag``, or when None the variable
    :data:`ALLOW_DIRTY_VARIABLE` set to 1."""
    return flag if flag is not None else os.environ.get(ALLOW_DIRTY_VARIABLE) == "1"


def write_bytes_atomic(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically, as :func:`write_text_atomic` writes text.

    Raises:
        WriteError: the file cannot be written, naming it.
    """
    _write_named(Path(path), data)


def _write_named(path: Path, data: str | bytes) -> None:
    """:func:`_write_atomic`, its failure named."""
    try:
        _write_atomic(path, data)
    except OSError as exc:
        raise WriteError(f"{path}: could not be written ({exc.strerror or exc}); the file there before, if any, is "
                         "unchanged") from None


def _write_atomic(path: Path, text: str | bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    for stale in path.parent.glob(f".{glob.escape(path.name)}.*.tmp"):  # left by a writer killed mid-write
        if not _writer_alive(stale, path.name):
            stale.unlink(missing_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.{os.getpid()}.", suffix=".tmp")
    try:
        binary = isinstance(text, bytes)
        with os.fdopen(fd, "wb" if binary else "w", **({} if binary else {"encoding": "utf-8"})) as handle:
            handle.write(text)
            handle.flush()
            if hasattr(os, "fchmod"):  # mkstemp makes 0600; files people share follow the umask
                os.fchmod(handle.fileno(), 0o666 & ~_current_umask())
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _writer_alive(temporary: Path, name: str) -> bool:
    """Whether the process that made ``temporary`` (``.<name>.<pid>.<random>.tmp``) still runs."""
    pid_text = temporary.name[len(name) + 2:].split(".", 1)[0]
    if not pid_text.isdigit():
        return False  # not made by this scheme: an older writer's, long gone
    pid = int(pid_text)
    if pid == os.getpid():
        return True  # this process: another thread may be writing
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # alive, owned by someone else
    return True


def splice_generated(text: str, start: str, end: str, body: str, *, where: str = "the file") -> str:
    """``text`` with ``body`` between the marker lines ``start`` and ``end`` (the first pair), markers kept.

    Raises:
        FFSRError: ``text`` lacks either marker; the message names ``where``.
    """
    if start not in text or end not in text:
        raise FFSRError(f"{where} lacks the markers {start!r} and {end!r}")
    head, rest = text.split(start, 1)
    _, tail = rest.split(end, 1)
    return f"{head}{start}\n{body}{end}{tail}"


def splice_file(path: str | Path, start: str, end: str, body: str) -> None:
    """Put ``body`` between the markers of the file at ``path`` (:func:`splice_generated`), written atomically:
    how a measurement's script writes its generated block into a docs page."""
    path = Path(path)
    write_text_atomic(path, splice_generated(path.read_text(encoding="utf-8"), start, end, body, where=str(path)))


def save_result(path: str | Path, data: Any) -> Any:
    """Write a measurement's ``data`` as JSON (:func:`write_json_atomic`) and return it as read back: what a
    script then prints and writes into the docs is exactly what the file holds."""
    write_json_atomic(path, data)
    return json.loads(json.dumps(data))


def json_text(data: Any, *, compact: bool = False) -> str:
    """``data`` as indented JSON text. ``compact`` (leaderboard entries) keeps the nesting of objects but writes a
    list of numbers or strings on one line and a list of objects one object per line, without spaces: an entry's
    thousands of episode rows and learning curves stay a few thousand lines, not a few hundred thousand. Either
    way the text parses to ``data``."""
    if not compact:
        return json.dumps(data, indent=2, sort_keys=False, allow_nan=False) + "\n"
    return _compact(json.loads(json.dumps(data, allow_nan=False)), 0) + "\n"  # as JSON has it: text keys, lists


def _compact(value: Any, level: int) -> str:
    inner, outer = "  " * (level + 1), "  " * level
    if isinstance(value, dict) and value:
        items = (f"{inner}{json.dumps(key)}: {_compact(item, level + 1)}" for key, item in value.items())
        return "{\n" + ",\n".join(items) + f"\n{outer}}}"
    if isinstance(value, list) and value and not all(isinstance(v, dict | list) for v in value):
        if not any(isinstance(v, dict | list) for v in value):
            return json.dumps(value, allow_nan=False)
    if isinstance(value, list) and value:
        lines = (inner + (json.dumps(v, separators=(",", ":"), allow_nan=False) if isinstance(v, dict)
                          else _compact(v, level + 1)) for v in value)
        return "[\n" + ",\n".join(lines) + f"\n{outer}]"
    return json.dumps(value, allow_nan=False)


def write_json_atomic(path: str | Path, data: Any, *, compact: bool = False) -> None:
    """Write ``data`` as indented JSON (:func:`json_text`), atomically (see :func:`write_text_atomic`)."""
    write_text_atomic(path, json_text(data, compact=compact))
