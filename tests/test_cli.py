import subprocess
import sys

import gyrotensegrity
from gyrohost.cli import COMMANDS, main


def test_version_matches_package(capsys):
    try:
        main(["--version"])
    except SystemExit as exc:
        assert exc.code == 0
    assert capsys.readouterr().out.strip() == f"gyrotens {gyrotensegrity.__version__}"


def test_help_lists_every_command():
    out = subprocess.run(
        [sys.executable, "-m", "gyrohost", "--help"], capture_output=True, text=True, check=True
    ).stdout
    for name in COMMANDS:
        assert name in out


def test_no_command_prints_help(capsys):
    assert main([]) == 0
    assert "usage: gyrotens" in capsys.readouterr().out
