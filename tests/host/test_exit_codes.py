"""Every subcommand's exit status for bad input is 2, with one error line starting with the
command's name and no traceback: a file that is not there, a port that is not there, an option
it does not know. Each case is refused before anything runs or is written."""

import pytest

from gyrohost.cli import COMMANDS, main

NO = "/nonexistent/gyrotens"
"""A path under a folder that does not exist."""

MISSING_FILE = {
    "demo": ["demo", "--config", f"{NO}/rig.toml", "-o", f"{NO}/out"],
    "simulate": ["simulate", f"{NO}/scene.toml", "-o", f"{NO}/run.npz"],
    "plan": ["plan", f"{NO}/scene.toml", "--target-attitude", "0,0,10", "-o", f"{NO}/plan.toml"],
    "plot": ["plot", f"{NO}/run.npz"],
    "rig": ["rig", "--config", f"{NO}/rig.toml"],
    "run": ["run", "--config", f"{NO}/rig.toml", "-o", f"{NO}/out"],
    "replay": ["replay", f"{NO}/log"],
    "export": ["export", f"{NO}/log"],
    "ports": ["ports", f"{NO}/ttyUSB0"],
    "doctor": ["doctor", "--config", f"{NO}/rig.toml"],
    "servo-setup": ["servo-setup", "zero", "--config", f"{NO}/rig.toml", "--servo", "s13"],
    "sil": ["sil", "--config", f"{NO}/rig.toml"],
    "sweep": ["sweep", f"{NO}/sweep.toml", "-o", f"{NO}/out"],
    "wheels": ["wheels", "calibrate", "--config", f"{NO}/rig.toml"],
    "servos": ["servos", "home", "--config", f"{NO}/rig.toml"],
    "imu": ["imu", "calibrate", "--config", f"{NO}/rig.toml"],
    "identify": ["identify", f"{NO}/log", "-o", f"{NO}/ident.toml"],
    "noise": ["noise", f"{NO}/log"],
}

NO_INPUT_FILE = {"bench"}
"""Commands that read no file (bench computes its cases and writes a report)."""

MISSING_PORT = [
    [
        "run",
        "--config",
        "sim-rig",
        "-o",
        f"{NO}/out",
        "--imu",
        f"{NO}/imu",
        "--wheels",
        f"{NO}/wheels",
        "--servos",
        f"{NO}/servos",
    ],  # fmt: skip
    ["ports", f"{NO}/ttyACM0"],
    ["servo-setup", "id", "--port", f"{NO}/ttyUSB0", "--new-id", "3"],
    ["wheels", "calibrate", "--port", f"{NO}/ttyACM0"],
    ["wheels", "calibrate", f"{NO}/ttyACM0"],  # the deprecated spelling
    ["wheels", "spin", "--port", f"{NO}/ttyACM0", "--wheel", "0", "--speed", "5"],
    ["servos", "jog", "--port", f"{NO}/ttyUSB0", "--servo", "s13", "--by-m", "0.01"],
    ["servos", "home", "--config", "sim-rig", "--port", f"{NO}/ttyUSB0"],
    ["imu", "calibrate", "--port", f"{NO}/rfcomm0"],
]


def test_every_command_has_a_missing_file_case():
    assert sorted([*MISSING_FILE, *NO_INPUT_FILE]) == sorted(COMMANDS)


def refused(argv, capsys) -> list[str]:
    """Run ``argv``; its exit status must be 2; its stderr lines."""
    try:
        status = main(argv)
    except SystemExit as exc:  # argparse's own usage errors
        status = exc.code
    captured = capsys.readouterr()
    assert status == 2, (argv, captured.out, captured.err)
    assert "Traceback" not in captured.err
    return captured.err.strip().splitlines()


@pytest.mark.parametrize("argv", MISSING_FILE.values(), ids=list(MISSING_FILE))
def test_a_missing_file_is_bad_input(argv, capsys):
    err = refused(argv, capsys)
    errors = [line for line in err if "error:" in line]
    assert len(errors) == 1 and errors[0].startswith(f"gyrotens {argv[0]}: error: "), err
    assert NO in errors[0] or "pip install 'gyrotensegrity[" in errors[0]  # or its missing extra


@pytest.mark.parametrize("argv", MISSING_PORT, ids=lambda a: " ".join(a[:2]))
def test_a_missing_port_is_bad_input_named_before_anything_is_announced(argv, capsys):
    err = refused(argv, capsys)
    errors = [line for line in err if ": error: " in line]  # a run's lists one port a line
    assert len(errors) == 1 and errors[0].startswith(f"gyrotens {argv[0]}: error: "), err
    assert "no such device" in "\n".join(err) and NO in "\n".join(err), err


@pytest.mark.parametrize("command", COMMANDS)
def test_an_unknown_option_is_bad_usage(command, capsys):
    err = refused([command, "--no-such-option"], capsys)
    assert err[-1].startswith(f"gyrotens {command}: error: "), err
