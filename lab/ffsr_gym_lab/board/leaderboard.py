"""Leaderboards of every benchmark version: JSON entries in the spec's folders, Markdown generated.

Each version's spec says where its entries live (``{env_id}`` or ``{version}/{task}`` under the
root), the names of its metrics and its ranking rule:

* ``feasible_then_iqm`` (v0): feasible rate (descending), then the IQM of B (ascending); an entry
  whose scenario hash differs from the current scenario file is *stale*: shown, not ranked.
* ``ci_separation`` (v2): the rank of an entry is 1 + the number of entries whose 95 % CI lies
  entirely above its own; entries with the same rank are marked tied.

Every aggregate is recomputed from the rows by the spec's score rule (:mod:`ffsr_gym.scoring.rules`).
"""

from __future__ import annotations

import hashlib
import json
import math
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from ffsr_gym.bench.board_layout import folder_of, groups, spec_of_entry, table_files
from ffsr_gym.bench.trace_file import file_problems, in_file
from ffsr_gym.bench.verify import entry_problems
from ffsr_gym.exceptions import FFSRError, InvalidInputError
from ffsr_gym.model.resources import scenario_names
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.model.spec import GENERATED_PAGES, BenchmarkSpec
from ffsr_gym.provenance import splice_generated, write_text_atomic
from ffsr_gym.scoring.rules import score_rule
from ffsr_gym.tasks.reference import reference_sha256
from ffsr_gym.user_files import parse_json, read_text
from ffsr_gym.versions.registry import all_specs, ranked_spec
from ffsr_gym_lab.board import rl_comparison, tables
from ffsr_gym_lab.board.paired import MEASURED_VERSIONS, paired_line
from ffsr_gym_lab.board.separation import levels_line


def load_entries(root: str | Path, spec: BenchmarkSpec) -> dict[str, list[dict[str, Any]]]:
    """A version's entries by table (env id or tier), each sorted by file name; missing folders are empty.

    Each entry carries ``_file``, ``_folder`` and ``_problems`` (:func:`ffsr_gym.bench.verify.entry_problems`;
    an unreadable file is an entry with that problem).
    """
    out = {}
    for group in groups(spec):
        folder = folder_of(spec, root, group)
        if "{task}" not in spec.leaderboard.folder and not folder.is_dir():
            continue  # an env id's table is shown once its folder exists
        out[group] = _refuse_duplicates([_load(path, spec, group) for path in table_files(folder)], group)
    return out


#: Within :func:`checks_once`: each entry's problems by (content digest, version, table).
_checked: dict[tuple[str, str, str], list[str]] | None = None


@contextmanager
def checks_once() -> Iterator[None]:
    """Within it, an entry file is checked once per content: one command that loads the entries several times
    (``leaderboard update``: tables, aggregates, figures, check) verifies each file once."""
    global _checked
    outer = _checked
    _checked = {} if outer is None else outer
    try:
        yield
    finally:
        _checked = outer


def _load(path: Path, spec: BenchmarkSpec, group: str) -> dict[str, Any]:
    """One entry file, verified; never raises for its content (nor hangs on a FIFO, nor reads a device)."""
    try:
        text = read_text(path)  # the text too: one command checks each content once (checks_once)
        entry = parse_json(text, str(path))
    except FFSRError as exc:
        return {"_file": path.name, "_folder": str(path.parent), "_problems": [f"not a readable JSON file ({exc})"]}
    if not isinstance(entry, dict):
        entry = {"_not_an_object": True}
    key = (hashlib.sha256(text.encode("utf-8", "surrogatepass")).hexdigest(), spec.version, group)
    if _checked is not None and key in _checked:
        problems = list(_checked[key])
    else:
        problems = entry_problems(entry, spec, group)
        if _checked is not None:
            _checked[key] = list(problems)
    record = entry.get("extra", {}).get("trace") if isinstance(entry.get("extra"), dict) else None
    if in_file(record):  # checked on every load: the file can change while the entry does not
        problems += file_problems(record, path, len(entry["episodes"]) if isinstance(entry.get("episodes"), list)
                                  else 0)
    if isinstance(entry.get("name"), str) and entry["name"] != path.stem:
        problems.append(f"name {entry['name']!r} is not its file's name {path.stem!r}; allowed: <name>.json")
    return entry | {"_file": path.name, "_folder": str(path.parent), "_problems": problems}


def _refuse_duplicates(items: list[dict[str, Any]], group: str) -> list[dict[str, Any]]:
    """Refuse, by name, entries of one table whose method names are the same (``ppo_easy`` and ``ppo`` in easy are
    both ``ppo`` in the summary): one method, one row."""
    names = Counter(tables.method_name(e, group) for e in items if not e["_problems"])
    for e in items:
        if not e["_problems"] and names[tables.method_name(e, group)] > 1:
            e["_problems"] = [f"method name {tables.method_name(e, group)!r} is taken by another entry of this table; "
                              "allowed: one entry per method (rename one)"]
    return items


def verified(entries: dict[str, list[dict[str, Any]]]) -> dict[str, list[dict[str, Any]]]:
    """The entries of :func:`load_entries` that verify, by table (what is ranked, aggregated and drawn)."""
    return {group: [e for e in items if not e["_problems"]] for group, items in entries.items()}


def refused(entries: dict[str, list[dict[str, Any]]]) -> list[tuple[str, str, list[str]]]:
    """(table, file, reasons) of every refused entry."""
    return [(group, e["_file"], e["_problems"]) for group, items in entries.items() for e in items if e["_problems"]]


def recompute(entry: dict[str, Any]) -> dict[str, Any]:
    """The aggregate metrics recomputed from the entry's episode rows by its version's score rule."""
    return score_rule(spec_of_entry(entry)).aggregate(entry["episodes"])


def entry_scenario(entry: dict[str, Any]) -> str | Path:
    """The scenario an entry names: a shipped scenario name, or a TOML file inside the entry's own folder.

    Raises:
        InvalidInputError: any other path (an entry file cannot make the renderer read files elsewhere).
    """
    scenario = entry["env_kwargs"].get("scenario", "paper")
    if isinstance(scenario, str) and scenario in scenario_names():
        return scenario
    folder = Path(entry.get("_folder", ".")).resolve()
    path = (folder / str(scenario)).resolve()
    if not isinstance(scenario, str) or path.suffix != ".toml" or not path.is_relative_to(folder):
        raise InvalidInputError(f"entry {entry.get('_file', entry.get('name'))!r}: env_kwargs.scenario = {scenario!r}; "
                                f"allowed: a shipped scenario {scenario_names()} or a .toml file inside {folder}")
    return path


def is_stale(entry: dict[str, Any]) -> bool:
    """Whether a single-scenario entry's scenario changed since it was scored."""
    return load_scenario(entry_scenario(entry)).sha256() != entry["provenance"]["scenario_sha256"].get("family")


def ranks(entries: list[dict[str, Any]], spec: BenchmarkSpec | None = None) -> list[int]:
    """``ci_separation``: 1 + the number of entries whose CI lower bound is above this entry's CI upper bound."""
    key = (spec or ranked_spec()).leaderboard.ci
    bounds = [e["metrics"][key] for e in entries]
    return [1 + sum(lo > hi for lo, _ in bounds) for _, hi in bounds]


def ordered(spec: BenchmarkSpec, items: list[dict[str, Any]]) -> list[tuple[str, dict[str, Any]]]:
    """(rank label, entry) in table order, by the spec's ranking rule."""
    names = spec.leaderboard
    if spec.leaderboard.ranking == "feasible_then_iqm":
        flags = [is_stale(e) for e in items]  # loads and hashes each entry's scenario once
        fresh = sorted((e for e, f in zip(items, flags) if not f),
                       key=lambda e: (-e["metrics"][names.rate], _inf(e["metrics"][names.iqm]), e["name"]))
        return [(str(r), e) for r, e in enumerate(fresh, start=1)] + [("stale", e) for e, f in zip(items, flags) if f]
    items = sorted(items, key=lambda e: (-e["metrics"][names.iqm], -e["metrics"][names.rate], -e["metrics"]["score_mean"]))
    rank_of = ranks(items, spec)
    counts = {r: rank_of.count(r) for r in rank_of}
    return [(f"{r}{' (tied)' if counts[r] > 1 else ''}", e) for r, e in zip(rank_of, items)]


def _inf(x: float | None) -> float:
    return math.inf if x is None else float(x)


def render_tables(spec: BenchmarkSpec, entries: dict[str, list[dict[str, Any]]]) -> str:
    """Markdown tables of one version, one per group with entries (v0: every env id, even empty).

    Refused entries (``_problems``) are never ranked: they are listed under the table with their reasons.
    """
    out = []
    every = spec.leaderboard.ranking == "feasible_then_iqm"
    for group, items in entries.items():
        if not items and not every:
            continue
        ranked = [e for e in items if not e.get("_problems")]
        out += tables.header(spec, group)
        out += [tables.row(spec, label, e) for label, e in ordered(spec, ranked)]
        out.append("")
        if not every and ranked:
            out += [levels_line(ranked, spec.leaderboard.ci, spec.leaderboard.iqm, spec.leaderboard.label), ""]
            paired = paired_line(ranked, spec.leaderboard.iqm, spec.leaderboard.label) \
                if spec.version in MEASURED_VERSIONS else ""
            out += [paired, ""] if paired else []
        for e in items:
            if e.get("_problems"):
                reasons = tables.free_text("; ".join(e["_problems"]), limit=400)
                out.append(f"* refused, not ranked: `{tables.safe(e['_file'])}`: {reasons}")
        if len(ranked) < len(items):
            out.append("")
    return "\n".join(out)


def render_readme(root: str | Path, loaded: dict[str, dict[str, list[dict[str, Any]]]] | None = None) -> str:
    """The leaderboard README with every version's tables between its markers.

    ``loaded``: each version's :func:`load_entries` by version, when the caller has them already.
    """
    path = Path(root) / "README.md"
    if not path.is_file():
        raise FFSRError(f"{path} does not exist; 'ffsr-gym leaderboard render --root {root}' creates it")
    text = path.read_text()
    for spec in all_specs().values():
        start, end = spec.leaderboard.markers()
        entries = loaded[spec.version] if loaded and spec.version in loaded else load_entries(root, spec)
        if not (start in text and end in text):
            if any(entries.values()):  # a version's entries are never left out of the tables unsaid
                raise FFSRError(f"{path} has no section for {spec.version}, whose entries are under {root}: add "
                                f"'## {spec.leaderboard.title}' with the lines {start!r} and {end!r}, then render "
                                "again")
        else:
            body = render_tables(spec, entries)
            if spec.version != ranked_spec().version and reference_sha256(spec.version):
                ranked = {group: [e for e in items if not e.get("_problems")] for group, items in entries.items()}
                body += "\n" + tables.headroom(spec, ranked) + "\n"  # the ranked version's is in its summary page
            text = splice_generated(text, start, end, body, where=str(path))
    return text


def write_readme(root: str | Path) -> bool:
    """Regenerate the tables in ``root/README.md``; returns whether the file changed.

    A folder without a README (a new leaderboard of one's own) gets one with every version's markers.

    Raises:
        InvalidInputError: ``root`` is not a folder.
    """
    root = Path(root)
    if not root.is_dir():
        raise InvalidInputError(f"leaderboard root {str(root)!r} is not a folder; create it and put entries in "
                                "the folders the benchmark specs name (e.g. <root>/FFSR-v0/ or <root>/v2/<tier>/)")
    path = root / "README.md"
    created = not path.exists()
    if created:
        sections = [f"## {spec.leaderboard.title}\n" + "\n".join(spec.leaderboard.markers()) + "\n"
                    for spec in sorted(all_specs().values(), key=lambda s: s.version, reverse=True)]
        write_text_atomic(path, "# Leaderboards\n\n" + "\n".join(sections))
    new = render_readme(root)
    if new == path.read_text():
        return created
    write_text_atomic(path, new)
    return True


def splice_summary(text: str, root: str | Path, spec: BenchmarkSpec | None = None,
                   entries: dict[str, list[dict[str, Any]]] | None = None, *, where: str = "the page",
                   loaded: dict[str, dict[str, list[dict[str, Any]]]] | None = None) -> str:
    """``text`` (the README or a docs page) with each generated leaderboard block it has regenerated: the live
    version's summary across tiers (with the aggregates across tiers under it, when
    ``<root>/<version>/aggregates.json`` exists), the top three per tier, the RL hyperparameter searches
    (``rl-search``) and the RL study against the classical entries (``rl-study``,
    :mod:`ffsr_gym_lab.board.rl_comparison`), and the same study on each other version (``rl-study-<version>``,
    its entries from ``loaded`` when given, else read).

    Raises:
        FFSRError: ``text`` has none of these blocks; the message names ``where``.
    """
    spec = spec or ranked_spec()
    entries = load_entries(root, spec) if entries is None else entries
    ranked_entries = verified(entries)
    blocks = {spec.leaderboard.markers("-summary"): lambda: _summary_body(root, spec, ranked_entries),
              spec.leaderboard.markers("-top3"): lambda: tables.top_three(spec, {
                  tier: ordered(spec, items) for tier, items in ranked_entries.items()}),
              _page_markers("rl-search"): tables.search_table,
              _page_markers("rl-study"): lambda: rl_comparison.table(spec, ranked_entries)}
    for version, other in all_specs().items():
        if version != spec.version:
            blocks[_page_markers(f"rl-study-{version}")] = lambda other=other: rl_comparison.table(other, verified(
                loaded[other.version] if loaded and other.version in loaded else load_entries(root, other)))
    present = [(markers, body) for markers, body in blocks.items() if markers[0] in text and markers[1] in text]
    if not present:
        raise FFSRError(f"{where} has none of the generated leaderboard blocks (markers such as "
                        f"{spec.leaderboard.markers('-summary')[0]!r})")
    for markers, body in present:
        text = splice_generated(text, *markers, body(), where=where)
    return text


def _page_markers(block: str) -> tuple[str, str]:
    command = f"ffsr-gym leaderboard render --readme {' '.join(GENERATED_PAGES)}"
    return f"<!-- {block}:start (generated by `{command}`) -->", f"<!-- {block}:end -->"


def _summary_body(root: str | Path, spec: BenchmarkSpec, ranked_entries: dict[str, list[dict[str, Any]]]) -> str:
    body = tables.summary(spec, ranked_entries, ranks)
    aggregated = Path(root) / spec.version / "aggregates.json"
    if aggregated.is_file():
        from ffsr_gym_lab.board.aggregates import markdown

        body += "\n" + markdown(aggregated)
    return body


def check(root: str | Path, readme: str | Path | list[str | Path] | None = None,
          loaded: dict[str, dict[str, list[dict[str, Any]]]] | None = None) -> list[str]:
    """Why the leaderboard under ``root`` cannot be published as it is: every refused entry (with its
    reasons) and every generated text that is out of date; empty when all is well. ``loaded``: each
    version's :func:`load_entries` by version, when the caller has them already."""
    specs = all_specs()
    if loaded is None:  # read and verified once
        loaded = {version: load_entries(root, spec) for version, spec in specs.items()}
    problems = [f"refused: {version} {group}/{name}: {'; '.join(reasons)}" for version, entries in loaded.items()
                for group, name, reasons in refused(entries)]
    if render_readme(root, loaded) != (Path(root) / "README.md").read_text():
        problems.append(f"out of date: {Path(root) / 'README.md'}; run ffsr-gym leaderboard render")
    ranked = ranked_spec()
    aggregated = Path(root) / ranked.version / "aggregates.json"
    if aggregated.is_file():
        from ffsr_gym_lab.board.aggregates import inputs

        if json.loads(aggregated.read_text()).get("inputs") != inputs(verified(loaded[ranked.version])):
            problems.append(f"out of date: {aggregated} (the entries changed); run ffsr-gym leaderboard aggregates")
    for page in [] if readme is None else [readme] if isinstance(readme, (str, Path)) else readme:
        text = Path(page).read_text(encoding="utf-8")
        if splice_summary(text, root, ranked, loaded[ranked.version], where=str(page), loaded=loaded) != text:
            problems.append(f"out of date: {page}; run ffsr-gym leaderboard render --readme {page}")
    return problems
