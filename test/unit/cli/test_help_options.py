"""Every ``--option`` that a command's help or the documentation names exists in that command's parser.

An option named after ``euc-ros OTHER`` on the same line is checked against OTHER's parser; options in
an ``args="..."`` attribute (a node's arguments in a launch-file example) are not ``euc-ros`` options.
"""
from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from euc_ros.cli.main import COMMANDS, build_parser

REPO = Path(__file__).resolve().parents[3]
OPTION = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*")
COMMAND = re.compile(r"euc-ros (" + "|".join(sorted(map(re.escape, COMMANDS), key=len, reverse=True)) + r")(?![\w-])")
NODE_ARGS = re.compile(r'args="[^"]*"')


def parsers(parser: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
    """The parser and every sub-command parser below it."""
    out = [parser]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                out += parsers(sub)
    return out


def command_parser(command: str) -> argparse.ArgumentParser:
    top = build_parser(command)
    sub = next(a for a in top._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[command]


def options_of(parser: argparse.ArgumentParser) -> set[str]:
    return {o for p in parsers(parser) for a in p._actions for o in a.option_strings}


_OPTIONS: dict[str, set[str]] = {}


def options(command: str) -> set[str]:
    if command not in _OPTIONS:
        _OPTIONS[command] = options_of(command_parser(command))
    return _OPTIONS[command]


def unknown_options(text: str, command: str | None, known=options) -> list[str]:
    """``--option`` names of ``text`` that the command they belong to lacks (``command``: the help's own).

    On each line an option belongs to the last ``euc-ros COMMAND`` before it, else to ``command``
    (None: the line's options are not checked).
    """
    bad = []
    for line in text.splitlines():
        line = NODE_ARGS.sub("", line)
        marks = [(m.end(), m.group(1)) for m in COMMAND.finditer(line)]
        for m in OPTION.finditer(line):
            owner = next((c for end, c in reversed(marks) if end <= m.start()), command)
            if owner is not None and m.group() not in known(owner):
                bad.append(f"{owner}: {m.group()} in {line.strip()!r}")
    return bad


def test_the_check_finds_an_option_that_does_not_exist():
    p = argparse.ArgumentParser(epilog="use --euc-body NAME; euc-ros play BAG --rate 2 --fast")
    p.add_argument("--euc-body")
    known = {"x": options_of(p), "play": {"--rate"}}.get
    assert unknown_options(p.format_help(), "x", known) == [
        "play: --fast in 'use --euc-body NAME; euc-ros play BAG --rate 2 --fast'"]
    assert unknown_options("  --body  the EUC's rigid body", "x", known) == [
        "x: --body in \"--body  the EUC's rigid body\""]


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_option_a_help_names_exists(command):
    bad = []
    for p in parsers(command_parser(command)):
        bad += unknown_options(p.format_help(), command)
    assert not bad, "\n".join(bad)


def _joined(text: str) -> str:
    """Shell continuation lines joined, so that a command's options stay on its line."""
    return re.sub(r"\\\n\s*", " ", text)


@pytest.mark.parametrize("doc", sorted((REPO / "docs").rglob("*.md")) + [REPO / "README.md"],
                         ids=lambda p: str(p.relative_to(REPO)))
def test_every_option_the_docs_give_a_command_exists(doc):
    bad = []
    for line in _joined(doc.read_text(encoding="utf-8")).splitlines():
        for part in re.split(r"`|\||;|&&", line):        # a pipe, a second command or the end of inline code
            bad += unknown_options(part, None)
    assert not bad, "\n".join(bad)
