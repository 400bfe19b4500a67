"""Results files survive concurrent writers: every write lands whole, no writer deletes another's temporary."""

from __future__ import annotations

import json
import multiprocessing
from pathlib import Path

from ffsr_gym.provenance import write_json_atomic


def _writer(path: str, tag: int, count: int, errors) -> None:
    payload = {"writer": tag, "rows": list(range(2000))}
    for k in range(count):
        try:
            write_json_atomic(Path(path), payload | {"k": k})
        except Exception as exc:  # noqa: BLE001 - counted: the test asserts there are none
            errors.put(f"{type(exc).__name__}: {exc}")


def test_two_processes_writing_one_file_300_times_each_raise_nothing(tmp_path):
    path = tmp_path / "entry.json"
    context = multiprocessing.get_context("spawn")
    errors = context.Queue()
    writers = [context.Process(target=_writer, args=(str(path), tag, 300, errors)) for tag in (1, 2)]
    for w in writers:
        w.start()
    for w in writers:
        w.join(120)
        assert w.exitcode == 0
    found = []
    while not errors.empty():
        found.append(errors.get())
    assert found == []
    final = json.loads(path.read_text())  # whole: it parses, and it is one writer's last write
    assert final["writer"] in (1, 2) and final["k"] == 299 and final["rows"] == list(range(2000))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["entry.json"]  # no temporary left behind


def test_compact_json_parses_back_as_json_would_and_keeps_a_row_per_line():
    from ffsr_gym.provenance import json_text

    data = {"name": "x", "extra": {1: (0.1, 2e-300, None), "nested": [{"a": [1, 2]}, [3, {"b": True}]]},
            "episodes": [{"seed": k, "score": k / 7, "rates": [k, -k]} for k in range(50)], "empty": [], "none": {}}
    text = json_text(data, compact=True)
    assert json.loads(text) == json.loads(json.dumps(data))  # int keys become text, tuples lists, floats exact
    lines = text.splitlines()
    assert sum(line.lstrip().startswith('{"seed":') for line in lines) == 50 and len(lines) < 80
    assert json.loads(json_text(data)) == json.loads(text)
