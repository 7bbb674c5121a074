"""The documentation follows the code: the CLI reference is the parser's, the README's test
command is the one CI runs."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from bulletnet.cli.reference import REFRESH, reference

ROOT = Path(__file__).resolve().parent.parent


def test_cli_reference_is_up_to_date():
    committed = (ROOT / "docs" / "cli.md").read_text(encoding="utf-8")
    assert committed == reference(), f"docs/cli.md is stale: refresh it with `{REFRESH}`"


def test_cli_reference_lists_every_command_and_option():
    # Reference: the parser itself, as argparse prints it in each command's --help
    from bulletnet.cli.main import build_parser

    text = reference()
    parser = build_parser()
    sub = parser._subparsers._group_actions[0]
    for name, command in sub.choices.items():
        assert f"\n## bulletnet {name}\n" in text
        section = text.split(f"\n## bulletnet {name}\n")[1].split("\n## ")[0]
        for option in command._option_string_actions:
            if option not in ("-h", "--help"):
                assert f"`{option}" in section or f", {option}" in section, (name, option)


def test_layout_in_development_md_is_the_tree():
    # reference: the tree itself (docs/layout.py reads every package, module, script, scene and
    # page): the layout section cannot miss a file or name one that is gone
    sys.path.insert(0, str(ROOT / "docs"))
    try:
        import layout
    finally:
        sys.path.pop(0)
    assert layout.page_block(layout.PAGE.read_text()) == layout.layout(), (
        "docs/development.md's layout is stale: run python docs/layout.py --write")


def test_readme_test_command_is_the_one_ci_runs():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    command = ("python3 -m venv .venv && .venv/bin/pip install -q -e '.[test]' && "
               ".venv/bin/python -m pytest -q")
    assert command in readme
    assert command in (ROOT / ".ci" / "run").read_text(encoding="utf-8")


def test_api_worked_example_runs(tmp_path):
    # the Python blocks of docs/api.md, run as one script, as a reader would paste them
    text = (ROOT / "docs" / "api.md").read_text(encoding="utf-8")
    blocks = [b.split("```")[0] for b in text.split("```python\n")[1:]]
    assert blocks
    proc = subprocess.run([sys.executable, "-c", "\n".join(blocks)], cwd=tmp_path,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("completed") and "refused:" in proc.stdout
    assert "125 nodes, 224 threads" in proc.stdout


def _anchors(markdown: str) -> set[str]:
    """GitHub's anchors of a page's headings: lower case, punctuation dropped, spaces to -."""
    return {re.sub(r"[^\w\- ]", "", line.lstrip("#").strip().lower()).replace(" ", "-")
            for line in markdown.splitlines() if line.startswith("#")}


def test_links_between_pages_resolve():
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    checked = 0
    for page in pages:
        text = page.read_text(encoding="utf-8")
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if target.startswith(("http://", "https://")):
                continue
            path, _, anchor = target.partition("#")
            resolved = (page.parent / path).resolve() if path else page
            assert resolved.exists(), f"{page.name}: broken link {target}"
            if anchor:
                assert anchor in _anchors(resolved.read_text(encoding="utf-8")), \
                    f"{page.name}: no heading for {target}"
            checked += 1
    assert checked > 20
