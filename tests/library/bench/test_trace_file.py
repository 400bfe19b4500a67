"""An entry's trace in a file beside it: lossless, smaller than the text, bound by its sha256, refused when swapped."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest

import ffsr_gym
from ffsr_gym.bench.replay import replay_entry
from ffsr_gym.bench.stamp import entry_digest
from ffsr_gym.bench.trace import decode
from ffsr_gym.bench.trace_file import FILE_FORMAT, SUFFIX, pack, store_entries, unpack
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.versions.registry import spec_for_version
from ffsr_gym_lab.board.leaderboard import load_entries


def wobble(obs):
    """A policy that is code (its actions depend on what it sees)."""
    return 0.4 * np.sin(obs[:12].astype(np.float64) * 1.7)


@pytest.fixture(scope="module")
def report():
    return ffsr_gym.evaluate(wobble, "FFSR-Residual-v2", task="easy", indices=[0, 1], name="mine")


def test_pack_is_lossless_on_every_bit_pattern_an_action_can_have():
    rng = np.random.default_rng(0)
    edges = np.array([-1.0, 1.0, -0.0, 0.0, np.float32(1e-45), -np.float32(1e-45), np.nextafter(np.float32(1), 0)],
                     np.float32)
    episodes = [rng.uniform(-1, 1, (200, 12)).astype(np.float32), np.zeros((0, 12), np.float32),
                np.resize(edges, (7, 12)).astype(np.float32), np.ones((1, 12), np.float32)]
    back = unpack(pack(episodes, 12), 12, 4, where="test")
    assert [a.tobytes() for a in back] == [a.tobytes() for a in episodes]  # -0.0 and subnormals included
    assert pack(episodes, 12) == pack(episodes, 12)  # a function of the actions: the same bytes every time


def test_unpack_refuses_what_is_not_the_trace_an_entry_states():
    data = pack([np.zeros((5, 3), np.float32)], 3)
    for wrong, width, episodes, match in ((data, 4, 1, "width 4"), (data, 3, 2, "2 episodes"),
                                          (b"not a trace", 3, 1, "not a trace file"),
                                          (data[:-8], 3, 1, "decompress"),
                                          (pack([np.full((5, 3), 2.0, np.float32)], 3), 3, 1, "outside")):
        with pytest.raises(InvalidInputError, match=match):
            unpack(wrong, width, episodes, where="test")


def test_save_writes_the_trace_beside_the_entry_and_verify_replays_it(tmp_path, report):
    path = report.save(tmp_path)
    stored = json.loads(path.read_text())["extra"]["trace"]
    trace = tmp_path / f"mine{SUFFIX}"
    assert stored["format"] == FILE_FORMAT and stored["file"] == trace.name and "episodes" not in stored
    assert stored["sha256"] == hashlib.sha256(trace.read_bytes()).hexdigest() and stored["episodes_count"] == 2
    texts = report.extra["trace"]["episodes"]
    assert trace.stat().st_size < sum(len(t) for t in texts)  # smaller than the text it replaces
    verdict = replay_entry(path)
    assert verdict.status == "reproduced" and "trace" in verdict.text


def test_a_swapped_or_missing_trace_file_is_refused_by_name(tmp_path, report):
    folder = tmp_path / "leaderboards" / "v2" / "easy"
    folder.mkdir(parents=True)
    saved = report.save(tmp_path)  # two tasks: the table itself would refuse the entry (its rows), besides its trace
    path = saved.rename(folder / saved.name)
    (tmp_path / f"mine{SUFFIX}").rename(folder / f"mine{SUFFIX}")
    trace = folder / f"mine{SUFFIX}"
    good = trace.read_bytes()
    actions = unpack(good, 12, 2, where="test")
    actions[1][50, 3] = np.nextafter(actions[1][50, 3], np.float32(2.0))
    trace.write_bytes(pack(actions, 12))  # one action one float32 step away
    with pytest.raises(InvalidInputError, match="not the file the entry was written with"):
        replay_entry(path)
    loaded = load_entries(tmp_path / "leaderboards", spec_for_version("v2"))["easy"]
    problems = [p for e in loaded for p in e["_problems"]]
    assert any("not the file the entry was written with" in p for p in problems)
    trace.unlink()
    with pytest.raises(InvalidInputError, match="extra.trace.file"):
        replay_entry(path)
    trace.write_bytes(good)
    entry = json.loads(path.read_text())
    entry["extra"]["trace"]["file"] = "../../../elsewhere.trace"  # a path that leaves the folder
    path.write_text(json.dumps(entry))
    with pytest.raises(InvalidInputError, match="allowed: 'mine.trace'"):
        replay_entry(path)


def test_moving_a_text_trace_keeps_every_action_and_the_replay(tmp_path, report):
    path = tmp_path / "mine.json"
    entry = report.to_json()
    entry["extra"]["verified"] = {"status": "reproduced"}  # a stamp of the text: it no longer holds
    path.write_text(json.dumps(entry, indent=2))
    [(moved, before, after, traced)] = store_entries([path, path])
    assert moved == path and after < before and traced
    assert store_entries([path]) == []  # done once
    stored = json.loads(path.read_text())
    texts, clipped = entry["extra"]["trace"]["episodes"], entry["extra"]["trace"]["clipped"]
    assert "verified" not in stored["extra"] and stored["extra"]["trace"]["clipped"] == clipped
    back = unpack((tmp_path / "mine.trace").read_bytes(), 12, 2, where="test")
    assert [a.tobytes() for a in back] == [decode(t, 12, where="t").tobytes() for t in texts]
    assert replay_entry(path).status == "reproduced"


def test_an_indented_entry_is_stored_compact_with_its_content_and_stamp(tmp_path, report):
    report.save(tmp_path)
    path = tmp_path / "mine.json"
    saved = path.read_text()
    entry = json.loads(saved)
    assert sum(line.lstrip().startswith('{"seed":') for line in saved.splitlines()) == len(entry["episodes"])
    path.write_text(json.dumps(entry, indent=2) + "\n")  # how entries were written before
    [(stored, before, after, traced)] = store_entries([path])
    assert stored == path and not traced and after < before
    assert path.read_text() == saved and json.loads(saved) == entry and entry_digest(json.loads(saved)) == entry_digest(entry)
    assert replay_entry(path).status == "reproduced"


def test_an_entry_saved_again_without_a_trace_leaves_no_trace_file(tmp_path, report):
    report.save(tmp_path)
    fixed = ffsr_gym.evaluate((0.0,) * 12, "FFSR-Residual-v2", task="easy", indices=[0, 1], name="mine")
    fixed.save(tmp_path, overwrite=True)
    assert not (tmp_path / f"mine{SUFFIX}").exists()

