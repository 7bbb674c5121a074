"""The documentation follows the code: the CLI reference is the parser's, the README's test
command is the one CI runs."""

from __future__ import annotations

from pathlib import Path

from bulletnet.cli_reference import REFRESH, reference

ROOT = Path(__file__).resolve().parent.parent


def test_cli_reference_is_up_to_date():
    committed = (ROOT / "docs" / "cli.md").read_text(encoding="utf-8")
    assert committed == reference(), f"docs/cli.md is stale: refresh it with `{REFRESH}`"


def test_cli_reference_lists_every_command_and_option():
    # Reference: the parser itself, as argparse prints it in each command's --help
    from bulletnet.cli import build_parser

    text = reference()
    parser = build_parser()
    sub = parser._subparsers._group_actions[0]
    for name, command in sub.choices.items():
        assert f"\n## bulletnet {name}\n" in text
        section = text.split(f"\n## bulletnet {name}\n")[1].split("\n## ")[0]
        for option in command._option_string_actions:
            if option not in ("-h", "--help"):
                assert f"`{option}" in section or f", {option}" in section, (name, option)


def test_readme_test_command_is_the_one_ci_runs():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    command = ("python3 -m venv .venv && .venv/bin/pip install -q -e '.[test]' && "
               ".venv/bin/python -m pytest -q")
    assert command in readme
    assert command in (ROOT / ".ci" / "run").read_text(encoding="utf-8")
