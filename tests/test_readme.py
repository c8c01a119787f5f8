"""The README says what the commands take (issue 19, defect 11)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from outcast_core.runtime.cli.main import build_parser

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")


def _subparser(name: str):
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    return sub.choices[name]


def test_no_link_outside_the_repository():
    assert "../" not in README


def test_quick_start_opens_the_app():
    quick = README.split("## Quick start", 1)[1].split("\n## ", 1)[0]
    assert "outcast-gui " in quick and "outcast relight " in quick


@pytest.mark.parametrize("command", ["relight", "shadow", "depth", "timelapse", "batch", "models"])
def test_every_option_is_in_the_synopsis(command):
    synopsis = README.split("## Command line", 1)[1].split("```", 2)[1]
    lines = [line for line in synopsis.splitlines() if line.strip()]
    start = next(i for i, line in enumerate(lines) if line.startswith(f"outcast {command} "))
    block = [lines[start]]
    for line in lines[start + 1 :]:
        if line.startswith("outcast "):
            break
        block.append(line)
    text = " ".join(block)
    for action in _subparser(command)._actions:
        if action.help == "==SUPPRESS==" or not action.option_strings or action.dest == "help":
            continue
        if action.dest == "full_res":  # kept for old scripts; --size full says the same
            continue
        assert any(re.search(rf"{re.escape(o)}\b", text) for o in action.option_strings), (
            command,
            action.option_strings,
        )


def test_documented_choices_exist():
    for command, option, value in re.findall(r"`(relight|shadow) (--\w+) (\w+)`", README):
        action = next(a for a in _subparser(command)._actions if option in a.option_strings)
        assert value in action.choices, (command, option, value)
    assert "`relight --shadows direct`" in README and "`relight --mode physics`" in README


def test_heading_help_says_it_needs_the_from_sun():
    heading = next(a for a in _subparser("timelapse")._actions if "--heading" in a.option_strings)
    assert "--from" in heading.help
