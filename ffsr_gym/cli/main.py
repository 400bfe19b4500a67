"""The ``ffsr-gym`` parser and entry point (:data:`DESCRIPTION` is what ``ffsr-gym --help`` says); the sub-commands
live in one module per group: the model and the paper, a user's policies, the verification of an entry. The lab's
sub-commands (the leaderboard's maintenance, the pools and studies, the docs pages) join from the entry point group
:data:`COMMANDS` (``ffsr_gym_lab.cli.lab_commands``): the library never imports them."""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any

from ffsr_gym.cli.model_commands import add_model_commands
from ffsr_gym.cli.policy_commands import add_policy_commands
from ffsr_gym.cli.verify_commands import add_verify_commands
from ffsr_gym.exceptions import FFSRError
from ffsr_gym.versions.registry import registered_ids

#: The entry point group whose callables ``add(sub, groups)`` add sub-commands (the lab's).
COMMANDS = "ffsr_gym.commands"
#: The lab's commands by name (``leaderboard`` sub-commands as "leaderboard <name>"), so that a user of the library
#: alone who types one is told where it lives instead of argparse's "invalid choice".
LAB_COMMANDS = ("tasks", "study", "dataset", "docs", *(f"leaderboard {name}" for name in
                                                       ("render", "update", "store", "plot", "aggregates", "pareto")))
DESCRIPTION = ("Dual-arm free-floating space robot: reproduce the paper's predefined-time planner, play and score "
               "the Gymnasium benchmark ({ids}), train baselines and verify leaderboard entries; with the lab "
               "(ffsr-gym-lab), build task pools and render leaderboards.")


class _DefaultsShown(argparse.HelpFormatter):
    """Every option's help ends with its default, unless the help text already names it."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if ("default" in text or not action.option_strings or action.required or action.default is argparse.SUPPRESS
                or isinstance(action, (argparse._StoreTrueAction, argparse._VersionAction, argparse._HelpAction))):
            return text
        value = action.default
        shown = "none" if value is None else " ".join(map(str, value)) if isinstance(value, (list, tuple)) else value
        return f"{text} (default: {shown})"


class _Parser(argparse.ArgumentParser):
    """The command line's parsers: each shows its options' defaults (sub-command parsers are of this class too)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", _DefaultsShown)
        super().__init__(*args, **kwargs)


def build_parser() -> argparse.ArgumentParser:
    """The ``ffsr-gym`` argument parser, every sub-command on it."""
    from importlib.metadata import entry_points, version

    parser = _Parser(prog="ffsr-gym", description=DESCRIPTION.format(ids=", ".join(registered_ids())),
                     epilog="Each command has its own --help. Documentation: README.md, the docs site (docs/, e.g. "
                            "docs/envs.md, docs/model.md, docs/tutorials/) and leaderboards/README.md.")
    parser.add_argument("--version", action="version", version=f"ffsr-gym {version('ffsr-gym')}")
    sub = parser.add_subparsers(dest="command", required=True)
    add_model_commands(sub)
    add_policy_commands(sub)
    groups = add_verify_commands(sub)
    for point in sorted(entry_points(group=COMMANDS), key=lambda p: p.name):
        try:
            add = point.load()
        except (ImportError, AttributeError, OSError) as exc:  # a package left over from another version: say so, go on
            owner = point.dist.name if point.dist is not None else "a package"
            print(f"ffsr-gym: warning: {owner}'s commands ({COMMANDS} entry point {point.name} = {point.value}) "
                  f"could not be loaded ({type(exc).__name__}: {exc}); reinstall it to use them", file=sys.stderr)
            continue
        add(sub, groups)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``ffsr-gym`` console script."""
    parser = build_parser()
    argv = sys.argv[1:] if argv is None else argv
    lab = _lab_command(parser, argv)
    if lab:
        print(f"ffsr-gym: error: '{lab}' is a command of the lab (ffsr-gym-lab), which is not installed; from a "
              "checkout: pip install -e ./lab (docs/layout.md, \"Library and lab\")", file=sys.stderr)
        return 2
    try:
        args = parser.parse_args(argv)
    except SystemExit as stop:  # argparse's named errors (a bad option, a number out of range) return 2
        if not stop.code:
            raise  # --help, --version
        return int(stop.code)
    args.argv = argv
    try:
        code = args.func(args)
    except FFSRError as exc:
        print(f"ffsr-gym: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the reader went away (``ffsr-gym info | head``): stop quietly, as other tools do
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    return int(code or 0)


def _lab_command(parser: argparse.ArgumentParser, argv: list[str]) -> str | None:
    """The lab command ``argv`` asks for when ``parser`` lacks it (the lab not installed), else None."""
    words = [word for word in argv if not word.startswith("-")][:2]
    for name in LAB_COMMANDS:
        first, _, second = name.partition(" ")
        if words[:1] != [first]:
            continue
        if not second and first not in _sub_choices(parser):
            return name
        if second and words[1:2] == [second] and second not in _sub_choices(_sub_choices(parser)[first]):
            return name
    return None


def _sub_choices(parser: argparse.ArgumentParser) -> dict[str, Any]:
    """A parser's sub-commands by name."""
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
