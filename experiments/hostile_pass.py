"""Replay the third hostile pass's reproductions against a checkout and count what each case got.

Run: ``python experiments/hostile_pass.py --repo PATH --label after`` (``PATH`` a checkout of
ffsr-gym, e.g. ``git worktree add /tmp/before f94047e``). Each case of
``experiments/hostile_cases.py`` runs in a fresh interpreter importing that checkout, in an empty
folder, with a time limit (a case past it is a ``hang``) and a 12 GiB address-space limit (so a
read of ``/dev/zero`` or a huge allocation fails instead of filling the machine). A case that
raises an ffsr-gym error is ``named``; any other exception is ``raw``; a process that dies is a
``crash``. The counts and every case's outcome go to ``experiments/hostile_pass.json`` under the
label, with the checkout's commit and the command (``--compare`` prints the labels side by side).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

from tqdm.auto import tqdm

sys.path.insert(0, str(Path(__file__).resolve().parent))
from hostile_cases import CASES, PREAMBLE  # noqa: E402 - the cases live beside this script

OUT = Path(__file__).resolve().parent / "hostile_pass.json"
KINDS = ("handled", "named", "code", "wrong", "loss", "hang", "raw", "crash")
RUNNER = r'''
{preamble}
from ffsr_gym.exceptions import FFSRError
def case():
{body}
try:
    case()
except FFSRError as exc:
    result("named", f"{{type(exc).__name__}}: {{exc}}")
except BaseException as exc:
    result("raw", f"{{type(exc).__name__}}: {{exc}}")
result("handled", "no result (the case fell through)")
'''
WARM_UP = ("import ffsr_gym, gymnasium as gym, numpy as np\n"
           "ffsr_gym.evaluate(lambda o: np.zeros(12, 'f4'), 'FFSR-Residual-v2', task='easy', indices=[0])\n"
           "ffsr_gym.evaluate((0.3, 4.0), 'FFSR-v2', task='easy', indices=[0, 1])\n")


def _limit_memory() -> None:
    limit = 12 * 2**30
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))


def run_case(repo: Path, body: str, timeout: float) -> dict[str, str]:
    """One case's outcome: its class and a note."""
    code = RUNNER.format(preamble=PREAMBLE, body="\n".join("    " + line for line in body.strip("\n").splitlines()))
    env = dict(os.environ, HOSTILE_REPO=str(repo), PYTHONPATH=str(repo), MPLBACKEND="Agg")
    with tempfile.TemporaryDirectory(prefix="hostile-") as folder:
        start = time.perf_counter()
        try:
            done = subprocess.run([sys.executable, "-c", code], cwd=folder, env=env, capture_output=True, text=True,
                                  timeout=timeout, preexec_fn=_limit_memory)
        except subprocess.TimeoutExpired:
            return {"class": "hang", "note": f"no end within {timeout:.0f} s"}
        seconds = time.perf_counter() - start
    for line in done.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[7:]) | {"seconds": round(seconds, 1)}
    tail = (done.stderr.strip().splitlines() or ["(nothing on stderr)"])[-1]
    return {"class": "crash", "note": f"exit {done.returncode}: {tail}"[:300], "seconds": round(seconds, 1)}


def _commit(repo: Path) -> str:
    out = subprocess.run(["git", "-C", str(repo), "rev-parse", "HEAD"], capture_output=True, text=True)
    return out.stdout.strip() or "unknown"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repo", type=Path, help="the checkout to try")
    parser.add_argument("--label", help="where the counts go in the results file (e.g. before, after)")
    parser.add_argument("--timeout", type=float, default=120.0, help="seconds a case may take (default: 120)")
    parser.add_argument("--only", nargs="+", default=None, help="case ids (default: all)")
    parser.add_argument("--compare", action="store_true", help="print the stored labels side by side and stop")
    args = parser.parse_args()
    stored = json.loads(OUT.read_text()) if OUT.is_file() else {}
    if args.compare:
        labels = list(stored)
        print("| class | " + " | ".join(labels) + " |")
        for kind in KINDS:
            print(f"| {kind} | " + " | ".join(str(stored[label]["counts"].get(kind, 0)) for label in labels) + " |")
        return
    repo = args.repo.resolve()
    subprocess.run([sys.executable, "-c", WARM_UP], cwd=tempfile.gettempdir(), check=True,
                   env=dict(os.environ, PYTHONPATH=str(repo)))  # compile the kernels once, before the timed cases
    cases = [c for c in CASES if args.only is None or c[0] in args.only]
    outcomes = {}
    for name, defect, what, body in tqdm(cases, desc=f"hostile pass on {repo.name}", unit="case"):
        outcomes[name] = {"defect": defect, "what": what} | run_case(repo, body, args.timeout)
        tqdm.write(f"{name}: {outcomes[name]['class']} ({outcomes[name]['note'][:120]})")
    from ffsr_gym.provenance import provenance, write_json_atomic

    if args.only and args.label in stored:  # a re-run of some cases: merged into the label's others
        if stored[args.label]["repo_commit"] != _commit(repo):
            raise SystemExit(f"--only: label {args.label!r} was run on another commit; run every case")
        outcomes = stored[args.label]["cases"] | outcomes
    stored[args.label] = {"repo_commit": _commit(repo), "counts": dict(Counter(o["class"] for o in outcomes.values())),
                          "cases": outcomes, "provenance": provenance(command=" ".join(["python", *sys.argv]))}
    write_json_atomic(OUT, stored)
    print(dict(Counter(o["class"] for o in outcomes.values())))


if __name__ == "__main__":
    main()
