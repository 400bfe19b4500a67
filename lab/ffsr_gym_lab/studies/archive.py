"""A study's bulky per-piece outputs out of the tree, and back: ``ffsr-gym study archive`` and ``study restore``.

A study folder keeps what a resume reads and the summaries; the outputs of its finished pieces that nothing reads
again unless someone asks (an RL seed's action traces, a search's absorbed lines) can leave it for an archive:
one ``.tar.xz`` file, written the same way from the same files (sorted members, no times or owners), published
where the project keeps release assets. The folder then holds :data:`MANIFEST`, which names every archived file
with its size and sha256, the archive's name, size and sha256, where it was published (a URL, when given) and the
commit whose tree last held the files. Nothing is lost: :func:`restore` brings the files back from the archive (a
local path or an http(s) URL) or from that commit of the git history, checking every byte against the manifest
and refusing a member that would leave the folder.
"""

from __future__ import annotations

import hashlib
import io
import json
import subprocess
import tarfile
import urllib.request
from pathlib import Path
from typing import Any

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.provenance import provenance, write_bytes_atomic, write_json_atomic

#: The manifest a study folder keeps for the files it archived.
MANIFEST = "archive.json"
FORMAT = "ffsr-gym-study-archive/1"
#: Largest archive :func:`restore` downloads (bytes): a study's outputs are tens of MB.
MAX_DOWNLOAD = 2 * 1024 ** 3


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _inside(name: str) -> bool:
    """Whether a relative name stays inside the folder it is taken in (not absolute, no ``..``)."""
    return bool(name) and not name.startswith("/") and ".." not in Path(name).parts


def _record_problem(record: Any) -> str | None:
    """What is wrong with one archive record of a manifest (a text file anyone can edit), or None."""
    if not isinstance(record, dict) or not isinstance(record.get("name"), str) or not isinstance(
            record.get("sha256"), str) or not isinstance(record.get("files"), dict):
        return "each of 'archives' must be an object with 'name', 'sha256' and 'files'"
    for name, file in record["files"].items():
        if not _inside(name):
            return f"file {name!r} of archive {record['name']!r} is not inside the study folder"
        if not isinstance(file, dict) or not isinstance(file.get("sha256"), str):
            return f"file {name!r} of archive {record['name']!r} has no 'sha256'"
    return None


def read_manifest(folder: Path) -> dict[str, Any]:
    """The folder's manifest, or an empty one (``archives``: one record per archive written).

    Raises:
        InvalidInputError: unreadable JSON, another format, or a record whose form or file names are wrong (named).
    """
    path = folder / MANIFEST
    if not path.is_file():
        return {"format": FORMAT, "archives": []}
    try:
        manifest = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise InvalidInputError(f"{path}: not a readable archive manifest ({exc})") from None
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
        raise InvalidInputError(f"{path}: key 'format' must be {FORMAT!r}")
    if not isinstance(manifest.get("archives"), list):
        raise InvalidInputError(f"{path}: key 'archives' must be a list")
    for record in manifest["archives"]:
        problem = _record_problem(record)
        if problem:
            raise InvalidInputError(f"{path}: key 'archives': {problem}")
    return manifest


def select(folder: Path, patterns: list[str]) -> list[Path]:
    """The files under ``folder`` that match a glob of ``patterns`` (relative to it), sorted, the manifest aside."""
    if not folder.is_dir():
        raise InvalidInputError(f"study folder {folder} does not exist")
    bad = [pattern for pattern in patterns if not _inside(pattern)]
    if bad:
        raise InvalidInputError(f"--pattern: {bad[0]!r}; allowed: a glob relative to the study folder, without '..'")
    found = {path for pattern in patterns for path in folder.glob(pattern) if path.is_file()}
    outside = [p for p in found if not p.resolve().is_relative_to(folder.resolve())]
    if outside:
        raise InvalidInputError(f"--pattern: {outside[0]} is outside the study folder {folder}")
    return sorted(p for p in found if p.name != MANIFEST)


def _tar(blobs: dict[str, bytes]) -> bytes:
    """Files by name as a tar.xz, the same bytes for the same files (sorted, no times, owners or modes)."""
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:xz", format=tarfile.PAX_FORMAT) as tar:
        for name in sorted(blobs):
            info = tarfile.TarInfo(name)
            info.size, info.mtime, info.mode, info.uid, info.gid = len(blobs[name]), 0, 0o644, 0, 0
            tar.addfile(info, io.BytesIO(blobs[name]))
    return buffer.getvalue()


def _members(data: bytes, where: str) -> dict[str, bytes]:
    """Every regular member of an archive's bytes by name; a link or a name that leaves the folder is refused."""
    out: dict[str, bytes] = {}
    try:
        with tarfile.open(fileobj=io.BytesIO(data), mode="r:xz") as tar:
            for info in tar.getmembers():
                name = info.name
                if not info.isfile() or not _inside(name):
                    raise InvalidInputError(f"{where}: member {name!r} is not a file inside the study folder")
                handle = tar.extractfile(info)
                out[name] = handle.read() if handle is not None else b""
    except (tarfile.TarError, EOFError, OSError, ValueError) as exc:
        raise InvalidInputError(f"{where}: not a readable tar.xz archive ({exc})") from None
    return out


def pack(folder: Path, patterns: list[str], out: Path, *, url: str | None = None) -> dict[str, Any]:
    """Archive the files of ``folder`` matching ``patterns`` into ``out`` and remove them, recording them in the
    manifest. The files are removed only after the archive, read back, gave every one of them bit for bit.

    Raises:
        InvalidInputError: no file matches, ``out`` is inside the folder, or an archive of that name is recorded.
    """
    folder, out = Path(folder), Path(out)
    files = select(folder, patterns)
    if not files:
        raise InvalidInputError(f"--pattern: no file of {folder} matches {patterns}")
    if out.resolve().is_relative_to(folder.resolve()):
        raise InvalidInputError(f"--out: {out} is inside the study folder; an archive goes out of the tree")
    manifest = read_manifest(folder)
    if any(record["name"] == out.name for record in manifest["archives"]):
        raise InvalidInputError(f"--out: {folder / MANIFEST} already records an archive named {out.name}")
    blobs = {p.relative_to(folder).as_posix(): p.read_bytes() for p in files}
    records = {name: {"bytes": len(blob), "sha256": _sha256(blob)} for name, blob in blobs.items()}
    data = _tar(blobs)
    back = _members(data, str(out))
    if {name: _sha256(blob) for name, blob in back.items()} != {n: r["sha256"] for n, r in records.items()}:
        raise InvalidInputError(f"{out}: the archive does not read back to the files it was made of")
    write_bytes_atomic(out, data)
    record = {"name": out.name, "bytes": len(data), "sha256": _sha256(data), "url": url,
              "git_commit": _commit_holding(folder, records), "files": records,
              "provenance": provenance(command=f"ffsr-gym study archive {folder}")}
    manifest["archives"].append(record)
    write_json_atomic(folder / MANIFEST, manifest)
    for path in files:
        path.unlink()
    return record


def _commit_holding(folder: Path, records: dict[str, dict[str, Any]]) -> str | None:
    """The checkout's HEAD when its tree holds every one of the files with the recorded bytes, else None."""
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=folder, capture_output=True, text=True)
    if head.returncode != 0:
        return None
    try:
        blobs = _from_git(folder, head.stdout.strip(), sorted(records))
    except InvalidInputError:
        return None
    same = all(_sha256(blobs[name]) == record["sha256"] for name, record in records.items())
    return head.stdout.strip() if same else None


def _read(source: str) -> bytes:
    """An archive's bytes from a local path or an http(s) URL."""
    if source.startswith(("http://", "https://")):
        with urllib.request.urlopen(source, timeout=60) as response:  # noqa: S310 - the scheme is checked above
            data = response.read(MAX_DOWNLOAD + 1)
        if len(data) > MAX_DOWNLOAD:
            raise InvalidInputError(f"--from: {source} is larger than {MAX_DOWNLOAD} bytes")
        return data
    path = Path(source)
    if not path.is_file():
        raise InvalidInputError(f"--from: {source} is not a file, an http(s) URL or git:<commit>")
    return path.read_bytes()


def _from_git(folder: Path, commit: str, names: list[str]) -> dict[str, bytes]:
    """The files as ``commit``'s tree held them (paths relative to ``folder``'s place in the checkout)."""
    root = subprocess.run(["git", "rev-parse", "--show-toplevel"], cwd=folder, capture_output=True, text=True)
    if root.returncode != 0:
        raise InvalidInputError(f"--from git:{commit}: {folder} is not in a git checkout")
    prefix = folder.resolve().relative_to(Path(root.stdout.strip()).resolve()).as_posix()
    out = {}
    for name in names:
        shown = subprocess.run(["git", "show", f"{commit}:{prefix}/{name}"], cwd=folder, capture_output=True)
        if shown.returncode != 0:
            raise InvalidInputError(f"--from git:{commit}: the commit has no {prefix}/{name}")
        out[name] = shown.stdout
    return out


def restore(folder: Path, source: str, *, archive: str | None = None) -> list[Path]:
    """Bring back archived files from ``source``: an archive as a local path or an http(s) URL (the recorded archive
    with its sha256), or ``git:<commit>`` (``git:`` alone: each archive's files from the commit it records), every
    archive of the folder, or the one named ``archive``. Every file is checked against its recorded sha256 before it
    is written; a file already there with those bytes is kept, one with other bytes is refused (nothing a user has
    is overwritten).

    Returns:
        The files written.
    """
    folder = Path(folder)
    records = read_manifest(folder)["archives"]
    if not records:
        raise InvalidInputError(f"{folder}: no archive is recorded ({MANIFEST} missing or empty)")
    names = [r["name"] for r in records]
    if archive is not None and archive not in names:
        raise InvalidInputError(f"--archive: {archive!r}; allowed: one of {names}")
    records = [r for r in records if archive in (None, r["name"])]
    if source.startswith("git:"):
        blobs = {}
        for record in records:
            commit = source[4:] or record.get("git_commit")
            if not commit:
                raise InvalidInputError(f"--from git: the manifest records no commit for {record['name']}")
            blobs[record["name"]] = _from_git(folder, commit, sorted(record["files"]))
    else:
        data = _read(source)
        digest = _sha256(data)
        records = [r for r in records if r["sha256"] == digest]
        if not records:
            raise InvalidInputError(f"--from: {source} has sha256 {digest}, which no archive of "
                                    f"{folder / MANIFEST} has (allowed: {names})")
        blobs = {records[0]["name"]: _members(data, source)}
    written = []
    for record in records:
        written += _write_back(folder, source, record, blobs[record["name"]])
    return written


def _write_back(folder: Path, source: str, record: dict[str, Any], blobs: dict[str, bytes]) -> list[Path]:
    """One archive's files written into ``folder`` from ``blobs``, each checked against the manifest first."""
    written = []
    for name in sorted(record["files"]):
        blob, want = blobs.get(name), record["files"][name]["sha256"]
        if blob is None or _sha256(blob) != want:
            raise InvalidInputError(f"{source}: {name} is missing or differs from the manifest's sha256 {want}")
        target = folder / name
        if target.exists():
            if _sha256(target.read_bytes()) != want:
                raise InvalidInputError(f"{target} exists with other bytes than the archived file; move it first")
            continue
        target.parent.mkdir(parents=True, exist_ok=True)
        write_bytes_atomic(target, blob)
        written.append(target)
    return written


def missing(folder: Path) -> list[str]:
    """The archived files of ``folder`` that are not in it now."""
    return sorted(name for record in read_manifest(Path(folder))["archives"] for name in record["files"]
                  if not (Path(folder) / name).is_file())

