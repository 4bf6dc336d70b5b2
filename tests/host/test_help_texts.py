"""Every subcommand's ``--help`` fits a screen and explains every option it lists."""

import argparse

import pytest

from gyrohost.cli import build_parser

SCREEN_LINES = 50
"""A terminal's height: a help longer than this scrolls its usage line away."""


def parsers() -> dict[str, argparse.ArgumentParser]:
    """``gyrotens CMD [VERB]`` -> its parser, nested verbs included."""
    out, todo = {}, list(build_parser().command_parsers.items())
    while todo:
        name, parser = todo.pop()
        out[name] = parser
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                todo += [(f"{name} {verb}", sub) for verb, sub in action.choices.items()]
    return out


PARSERS = parsers()


@pytest.mark.parametrize("name", sorted(PARSERS))
def test_the_help_fits_a_screen_and_explains_every_option(name):
    parser = PARSERS[name]
    lines = parser.format_help().splitlines()
    assert len(lines) <= SCREEN_LINES, f"gyrotens {name} --help: {len(lines)} lines"
    unexplained = [
        "/".join(a.option_strings) or a.dest
        for a in parser._actions
        if not a.help and not isinstance(a, argparse._SubParsersAction)
    ]
    assert not unexplained, f"gyrotens {name}: no help for {unexplained}"
