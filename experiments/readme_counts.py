"""The README's length, counted as the peers' READMEs are (lines, and words as ``wc -w`` splits them), at HEAD and
at any other commits given, from the git history.

Run: ``python experiments/readme_counts.py f94047e`` (prints a Markdown table; writes nothing).
"""

from __future__ import annotations

import argparse
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def counts(text: str) -> tuple[int, int]:
    """(lines, words) of ``text``: newline-terminated lines, whitespace-separated words."""
    return len(text.splitlines()), len(text.split())


def readme_at(commit: str) -> str:
    """README.md as committed at ``commit`` (``worktree``: the file as it is now)."""
    if commit == "worktree":
        return (ROOT / "README.md").read_text(encoding="utf-8")
    return subprocess.run(["git", "show", f"{commit}:README.md"], cwd=ROOT, capture_output=True, text=True,
                          check=True).stdout


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("commits", nargs="*", help="other commits to count (e.g. f94047e)")
    args = parser.parse_args()
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                          check=True).stdout.strip()
    print("| README of ffsr-gym at | lines | words |\n|---|---|---|")
    for commit in [*args.commits, head, "worktree"]:
        lines, words = counts(readme_at(commit))
        print(f"| {commit} | {lines} | {words:,} |")


if __name__ == "__main__":
    main()
