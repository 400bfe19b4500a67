"""The fourth hostile pass on entries and stamps: no forged entry reaches a table or a stamp, no model is unpickled
without consent, and text an author typed renders inert. Each test failed before its guard."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from ffsr_gym.cli.main import main
from ffsr_gym.exceptions import InvalidInputError, UserFileError
from ffsr_gym.user_files import parse_json
from ffsr_gym.versions.registry import ranked_spec
from ffsr_gym_lab.board import leaderboard, tables

ROOT = Path(__file__).resolve().parents[3]
ENTRY = Path("v2") / "easy" / "cmaes_v2.json"  # a planner entry: its replay takes seconds


def _reasons(root: Path, name: str) -> list[str]:
    """Why the easy table refuses its entry file ``name``."""
    return next(e["_problems"] for e in leaderboard.load_entries(root, ranked_spec())["easy"] if e["_file"] == name)


@pytest.fixture(scope="module")
def stamped_once(tmp_path_factory) -> Path:
    """The entry, freshly stamped by ``verify --stamp`` (one replay for the module)."""
    folder = tmp_path_factory.mktemp("stamped")
    shutil.copy(ROOT / "leaderboards" / ENTRY, folder / ENTRY.name)
    assert main(["leaderboard", "verify", str(folder / ENTRY.name), "--stamp"]) == 0
    return folder / ENTRY.name


@pytest.fixture()
def stamped(tmp_path, stamped_once) -> tuple[Path, Path]:
    """A leaderboard root holding the stamped entry in its table and v0's tables."""
    root = tmp_path / "leaderboards"
    (root / ENTRY).parent.mkdir(parents=True)
    shutil.copy(stamped_once, root / ENTRY)
    for folder in ("FFSR-v0", "FFSR-Residual-v0"):
        shutil.copytree(ROOT / "leaderboards" / folder, root / folder)
    assert _reasons(root, ENTRY.name) == []
    return root, root / ENTRY


def test_json_with_a_key_twice_or_a_non_finite_constant_is_refused():
    for text, words in (('{"score": 0.1, "score": 0.9}', "key 'score' appears twice"),
                        ('{"rows": [{"a": 1, "b": 2, "a": 3}]}', "key 'a' appears twice"),
                        ('{"provenance": {"wall_time_s": NaN}}', "NaN is not a JSON number"),
                        ('[Infinity]', "Infinity is not a JSON number")):
        with pytest.raises(UserFileError, match=words):
            parse_json(text, "entry.json")
    assert parse_json('{"a": {"a": 1}}', "x") == {"a": {"a": 1}}  # the same key in two objects is fine


def test_a_stamp_copied_with_the_rows_under_another_name_or_typed_by_hand_is_refused(stamped):
    root, path = stamped
    entry = json.loads(path.read_text())
    copy = dict(entry, name="cmaes_copy")  # rows and stamp copied under another name
    (path.parent / "cmaes_copy.json").write_text(json.dumps(copy))
    assert any("entry_sha256 differs" in r for r in _reasons(root, "cmaes_copy.json"))
    typed = json.loads(json.dumps(entry))
    typed["extra"]["verified"]["commit"] = "0" * 40  # "verified at 00000000"
    path.write_text(json.dumps(typed))
    assert any("not a commit of this repository" in r for r in _reasons(root, path.name))
    typed["extra"]["verified"]["commit"] = "00000000"
    path.write_text(json.dumps(typed))
    assert any("40-digit hexadecimal commit" in r for r in _reasons(root, path.name))
    typed["extra"]["verified"] |= {"commit": None, "verifier": "[me](http://example.com)"}
    path.write_text(json.dumps(typed))
    assert any("extra.verified.verifier" in r for r in _reasons(root, path.name))
    forged = json.loads(json.dumps(entry))
    forged["provenance"]["command"] = "edited after the stamp"  # any field, not only the rows
    path.write_text(json.dumps(forged))
    assert any("entry_sha256 differs" in r for r in _reasons(root, path.name))


def test_a_stamp_on_a_version_that_carries_none_is_refused(stamped):
    from ffsr_gym.versions.registry import all_specs

    root, path = stamped
    spec = all_specs()["v0"]
    group, items = next((g, items) for g, items in leaderboard.load_entries(root, spec).items() if items)
    v0 = Path(items[0]["_folder"]) / items[0]["_file"]
    entry = json.loads(v0.read_text())
    entry.setdefault("extra", {})["verified"] = json.loads(path.read_text())["extra"]["verified"]
    v0.write_text(json.dumps(entry))
    reloaded = next(e for e in leaderboard.load_entries(root, spec)[group] if e["_file"] == v0.name)
    assert any("carry no stamp" in r for r in reloaded["_problems"])


def test_verify_stamps_the_bytes_it_replayed_and_never_a_link(stamped, monkeypatch, capsys):
    from ffsr_gym.bench import replay
    from ffsr_gym.cli import verify_commands

    _, path = stamped
    genuine = path.read_text()
    real_replay = replay._replay

    def swap_during_replay(where, text, run_code):  # rows swapped in while the genuine ones replay
        verdict = real_replay(where, text, run_code)
        forged = json.loads(genuine)
        forged["episodes"][0]["score"] = 1.0
        where.write_text(json.dumps(forged))
        return verdict

    monkeypatch.setattr(replay, "_replay", swap_during_replay)
    assert main(["leaderboard", "verify", str(path), "--stamp"]) == 2
    assert "changed while it was replayed; nothing stamped" in capsys.readouterr().err
    assert json.loads(path.read_text())["episodes"][0]["score"] == 1.0  # left as found, unstamped anew
    monkeypatch.setattr(replay, "_replay", real_replay)
    path.write_text(genuine)
    link = path.parent / "linked.json"
    link.symlink_to(path)
    with pytest.raises(InvalidInputError, match="symbolic link"):
        verify_commands.write_stamp(str(link), genuine)
    assert link.is_symlink()


def test_text_an_author_typed_renders_inert_and_bounded():
    hostile = "[click](http://evil.example) ![img](http://evil.example/x.png) www.evil.example <b>x</b> " + "A" * 500
    cell = tables.free_text(hostile)
    assert cell.startswith("`") and cell.endswith("`") and cell.count("`") == 2  # one code span: nothing renders
    assert len(cell) <= tables.FREE_TEXT_CHARS + 2 and cell.endswith("\u2026`") and "<" not in cell
    assert tables.free_text("back`tick|pipe") == "`back'tick/pipe`"
    assert "`" not in tables.free_text("`" * 100)[1:-1]
    text = tables.compute_text({"hardware": hostile})
    assert text.count("`") == 2 and len(text) <= tables.FREE_TEXT_CHARS + 2


def test_the_pareto_study_loads_no_model_without_consent(tmp_path):
    from ffsr_gym_lab.board.pareto import task_pareto

    with pytest.raises(InvalidInputError, match="--trust-model"):
        task_pareto(tmp_path, tmp_path / "p.json", tmp_path, load_model=lambda algo, where: None)

def test_the_pareto_command_asks_for_consent_before_any_work(tmp_path, capsys):
    assert main(["leaderboard", "pareto", "--root", str(tmp_path), "--models", str(tmp_path)]) == 2
    assert "--trust-model" in capsys.readouterr().err
