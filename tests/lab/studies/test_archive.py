"""A study's archive: files out of the tree into a tar.xz recorded by sha256, and back from the archive (a path or an
http URL) or from git history, byte for byte; a changed archive, a member that leaves the folder or a user's file
with other bytes is refused by name."""

from __future__ import annotations

import functools
import hashlib
import http.server
import io
import json
import subprocess
import tarfile
import threading
from pathlib import Path

import numpy as np
import pytest

from ffsr_gym.cli.main import main
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym_lab.studies import archive

PATTERN = ["*/evaluation*.trace"]


def _git(cwd: Path, *args: str) -> str:
    return subprocess.run(["git", *args], cwd=cwd, check=True, capture_output=True, text=True).stdout.strip()


@pytest.fixture
def study(tmp_path):
    """A committed study folder: two seeds with a trace and an evaluation each; the traces' sha256 by name."""
    repo = tmp_path / "repo"
    folder = repo / "studies" / "rl"
    rng = np.random.default_rng(7)
    traces = {}
    for seed in (0, 1):
        (folder / f"seed{seed}").mkdir(parents=True)
        blob = rng.bytes(20_000 + seed)
        (folder / f"seed{seed}" / "evaluation.trace").write_bytes(blob)
        (folder / f"seed{seed}" / "evaluation.json").write_text(json.dumps({"seed": seed}))
        traces[f"seed{seed}/evaluation.trace"] = hashlib.sha256(blob).hexdigest()
    _git(repo, "init", "-q")
    _git(repo, "-c", "user.name=t", "-c", "user.email=t@t", "add", ".")
    _git(repo, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "study")
    return folder, traces, tmp_path / "release" / "rl-traces.tar.xz"


def test_archive_moves_the_matching_files_out_and_records_each_by_sha256(study):
    folder, traces, out = study
    record = archive.pack(folder, PATTERN, out, url="https://example.org/rl-traces.tar.xz")
    assert {n: f["sha256"] for n, f in record["files"].items()} == traces
    assert record["sha256"] == hashlib.sha256(out.read_bytes()).hexdigest()
    assert record["git_commit"] == _git(folder, "rev-parse", "HEAD")
    assert not list(folder.glob("*/evaluation.trace")) and len(list(folder.glob("*/evaluation.json"))) == 2
    assert archive.missing(folder) == sorted(traces)
    manifest = json.loads((folder / archive.MANIFEST).read_text())
    assert manifest["archives"][0]["url"] == "https://example.org/rl-traces.tar.xz"


def test_the_same_files_give_the_same_archive_bytes(study, tmp_path):
    folder, _, out = study
    copy = tmp_path / "copy"
    subprocess.run(["cp", "-r", str(folder), str(copy)], check=True)
    first = archive.pack(folder, PATTERN, out)
    second = archive.pack(copy, PATTERN, tmp_path / "other" / out.name)
    assert first["sha256"] == second["sha256"]


def test_restore_from_the_archive_gives_the_bytes_back_and_keeps_what_is_there(study):
    folder, traces, out = study
    archive.pack(folder, PATTERN, out)
    written = archive.restore(folder, str(out))
    assert {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest() for p in written} == traces
    assert archive.restore(folder, str(out)) == [] and archive.missing(folder) == []


def test_restore_from_git_history(study):
    folder, traces, out = study
    archive.pack(folder, PATTERN, out)
    out.unlink()  # the release asset is gone: the history still has the files
    written = archive.restore(folder, "git:")
    assert {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest() for p in written} == traces


def test_restore_over_http(study):
    folder, traces, out = study
    archive.pack(folder, PATTERN, out)
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(out.parent))
    handler.log_message = lambda *a: None
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        written = archive.restore(folder, f"http://127.0.0.1:{server.server_address[1]}/{out.name}")
    finally:
        server.shutdown()
    assert len(written) == len(traces)


def test_a_changed_archive_is_refused_and_nothing_is_written(study):
    folder, _, out = study
    archive.pack(folder, PATTERN, out)
    data = bytearray(out.read_bytes())
    data[len(data) // 2] ^= 0xFF
    out.write_bytes(bytes(data))
    with pytest.raises(InvalidInputError, match="sha256"):
        archive.restore(folder, str(out))
    assert archive.missing(folder) != []


def test_a_member_that_leaves_the_folder_is_refused(study, tmp_path):
    folder, _, out = study
    archive.pack(folder, PATTERN, out)
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:xz") as tar:
        info = tarfile.TarInfo("../../outside.trace")
        info.size = 3
        tar.addfile(info, io.BytesIO(b"bad"))
    evil = tmp_path / "evil.tar.xz"
    evil.write_bytes(buffer.getvalue())
    manifest = json.loads((folder / archive.MANIFEST).read_text())
    manifest["archives"][0]["sha256"] = hashlib.sha256(evil.read_bytes()).hexdigest()
    (folder / archive.MANIFEST).write_text(json.dumps(manifest))
    with pytest.raises(InvalidInputError, match="not a file inside the study folder"):
        archive.restore(folder, str(evil))
    assert not (folder.parent.parent / "outside.trace").exists()


def test_a_users_file_with_other_bytes_is_not_overwritten(study):
    folder, _, out = study
    archive.pack(folder, PATTERN, out)
    mine = folder / "seed0" / "evaluation.trace"
    mine.write_bytes(b"my own work")
    with pytest.raises(InvalidInputError, match="exists with other bytes"):
        archive.restore(folder, str(out))
    assert mine.read_bytes() == b"my own work"


def test_bad_requests_are_named(study, tmp_path):
    folder, _, out = study
    with pytest.raises(InvalidInputError, match="inside the study folder"):
        archive.pack(folder, PATTERN, folder / "x.tar.xz")
    with pytest.raises(InvalidInputError, match="no file"):
        archive.pack(folder, ["*.nothing"], out)
    with pytest.raises(InvalidInputError, match="no archive is recorded"):
        archive.restore(folder, str(out))
    archive.pack(folder, PATTERN, out)
    with pytest.raises(InvalidInputError, match="already records"):
        archive.pack(folder, ["*/evaluation.json"], out)
    with pytest.raises(InvalidInputError, match="is not a file"):
        archive.restore(folder, str(tmp_path / "nowhere.tar.xz"))


def test_the_commands(study, capsys):
    folder, traces, out = study
    assert main(["study", "archive", str(folder), "--pattern", PATTERN[0], "--out", str(out)]) == 0
    assert f"archived {len(traces)} files" in capsys.readouterr().out
    assert main(["study", "missing", str(folder)]) == 0
    assert capsys.readouterr().out.split() == sorted(traces)
    assert main(["study", "restore", str(folder), "--from", str(out), "--archive", "nope"]) == 2
    assert "--archive" in capsys.readouterr().err
    assert main(["study", "restore", str(folder), "--from", str(out)]) == 0
    assert archive.missing(folder) == []


def test_a_folder_with_two_archives(study, tmp_path):
    folder, traces, out = study
    first = archive.pack(folder, ["seed0/evaluation.trace"], out)
    second = archive.pack(folder, ["seed1/evaluation.trace"], tmp_path / "release" / "second.tar.xz")
    assert (first["name"], second["name"]) == ("rl-traces.tar.xz", "second.tar.xz")
    written = archive.restore(folder, str(tmp_path / "release" / "second.tar.xz"))  # the archive its sha256 names
    assert [p.relative_to(folder).as_posix() for p in written] == ["seed1/evaluation.trace"]
    assert archive.missing(folder) == ["seed0/evaluation.trace"]
    (folder / "seed1" / "evaluation.trace").unlink()
    assert len(archive.restore(folder, "git:")) == 2  # every archive, each from the commit it records
    assert archive.missing(folder) == []
    with pytest.raises(InvalidInputError, match="allowed: one of"):
        archive.restore(folder, "git:", archive="third.tar.xz")


@pytest.mark.parametrize("edit, named", [
    (lambda m: m["archives"][0]["files"].update({"../../outside.trace": {"bytes": 3, "sha256": "0" * 64}}),
     "not inside the study folder"),
    (lambda m: m["archives"][0].pop("files"), "'name', 'sha256' and 'files'"),
    (lambda m: m.update(archives={}), "key 'archives' must be a list"),
])
def test_a_manifest_edited_by_hand_is_refused_by_name(study, edit, named):
    folder, _, out = study
    archive.pack(folder, PATTERN, out)
    manifest = json.loads((folder / archive.MANIFEST).read_text())
    edit(manifest)
    (folder / archive.MANIFEST).write_text(json.dumps(manifest))
    with pytest.raises(InvalidInputError, match=named):
        archive.restore(folder, "git:")
    assert not (folder.parent.parent / "outside.trace").exists()


@pytest.mark.parametrize("pattern", ["/etc/*", "../*/evaluation.trace"])
def test_a_pattern_that_leaves_the_folder_is_refused(study, pattern):
    folder, _, out = study
    with pytest.raises(InvalidInputError, match="--pattern"):
        archive.pack(folder, [pattern], out)
