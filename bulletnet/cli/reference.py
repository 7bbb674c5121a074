"""The CLI reference in Markdown, generated from the argparse parser of :mod:`bulletnet.cli.main`
so that it cannot drift from it.

    python -m bulletnet.cli.reference docs/cli.md     # rewrite the committed reference
    python -m bulletnet.cli.reference                 # print it
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .main import build_parser, default_text

REFRESH = "python -m bulletnet.cli.reference docs/cli.md"
"""The command that rewrites ``docs/cli.md``."""


def _name(action: argparse.Action) -> str:
    """How an argument is written: ``--dt S``, ``--bending, --no-bending``, ``SCENE``."""
    if not action.option_strings:
        return action.metavar or action.dest.upper()
    if action.nargs == 0:
        return ", ".join(action.option_strings)
    metavar = action.metavar or action.dest.upper()
    if action.choices is not None and action.metavar is None:
        metavar = "{" + ",".join(action.choices) + "}"
    if action.nargs in ("+", "*"):
        metavar += " ..."
    return ", ".join(f"{o} {metavar}" for o in action.option_strings)


def _default(action: argparse.Action) -> str:
    return " ".join(f"`{v}`" for v in default_text(action))


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def _table(parser: argparse.ArgumentParser) -> list[str]:
    rows = ["| argument | meaning | default |", "|---|---|---|"]
    for action in parser._actions:
        if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
            continue
        meaning = action.help or ""
        if action.required and action.option_strings:
            meaning += " (required)"
        if action.nargs == "?":
            meaning += " (optional)"
        rows.append(f"| `{_cell(_name(action))}` | {_cell(meaning)} | {_default(action)} |")
    return rows


def _synopsis(prog: str, parser: argparse.ArgumentParser) -> str:
    words = [prog]
    for action in parser._actions:
        if not action.option_strings and not isinstance(action, argparse._SubParsersAction):
            name = action.metavar or action.dest.upper()
            words.append({"?": f"[{name}]", "+": f"{name} [{name} ...]",
                          "*": f"[{name} ...]"}.get(action.nargs, name))
    return " ".join(words) + " [options]"


def reference(parser: argparse.ArgumentParser | None = None) -> str:
    """The Markdown reference of ``parser`` (default: the ``bulletnet`` command) and its
    subcommands, in the parser's order."""
    parser = parser or build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    summaries = {a.dest: a.help for a in sub._choices_actions}
    lines = [f"# `{parser.prog}` command reference", "",
             f"<!-- generated from bulletnet/cli/main.py by `{REFRESH}`; do not edit -->", "",
             _cell(parser.description or ""), "",
             "Exit codes: 0 done, 2 bad input (one line on stderr), 3 a diverged run, "
             "130 interrupted (Ctrl-C or SIGTERM).", "",
             "| command | what it does |", "|---|---|"]
    lines += [f"| [`{name}`](#{parser.prog}-{name}) | {_cell(summaries[name])} |"
              for name in sub.choices]
    lines += ["", "Options of the command itself:", ""] + _table(parser)
    for name, command in sub.choices.items():
        summary = _cell(summaries[name])
        lines += ["", f"## {parser.prog} {name}", "", summary[:1].upper() + summary[1:] + ".", "",
                  "```", _synopsis(f"{parser.prog} {name}", command), "```", ""]
        lines += _table(command)
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    text = reference()
    if args:
        Path(args[0]).write_text(text, encoding="utf-8")
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
