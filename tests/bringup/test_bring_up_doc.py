"""docs/bring-up.md's transcripts are what the commands print: each ``<!-- transcript -->``
block's commands run against the simulated rig (``my-rig.toml``: the lab-rig template with its
refused keys filled in, on the rig's ports), and every line of the block, numbers and paths
aside, is a line of the output (``...`` skips lines)."""

import re
import shlex
import time
from pathlib import Path

from bringup_rig import config_text

from gyrohost.cli import main
from gyrohost.drivers import wheelproto as wp

DOC = Path(__file__).resolve().parents[2] / "docs" / "bring-up.md"
BLOCK = re.compile(r"<!-- transcript -->\n```text\n(.*?)```", re.S)
PATH = re.compile(r"(?<![\w.])(/[^\s,;)]+|[\w.-]+\.toml)")
NUMBER = re.compile(r"[-+]?\d+(\.\d+)?")
NOUN_PORT = {"imu": "imu", "wheels": "wheels", "servos": "servos"}
SLACK = ["--imu-rate-tolerance", "0.9"]
"""The doctor's IMU rate may be far off on a loaded machine serving the emulators."""


def shape(line: str) -> str:
    return NUMBER.sub("<n>", PATH.sub("<path>", line.rstrip()))


def transcripts() -> list[tuple[str, list[str]]]:
    """(command line, expected output lines) of every transcript block, in order."""
    out = []
    for block in BLOCK.findall(DOC.read_text()):
        for line in block.splitlines():
            if line.startswith("$ "):
                out.append((line[2:], []))
            else:
                out[-1][1].append(line)
    return out


def argv_for(command: str, config: str, ports: dict[str, str]) -> list[str]:
    argv = [config if a == "my-rig.toml" else a for a in shlex.split(command)[1:]]
    if "--port" in argv:
        argv[argv.index("--port") + 1] = ports[NOUN_PORT[argv[0]]]
    if argv[0] == "ports":  # the rig's ptys, which no USB listing finds; a pty shares the CPU
        argv = ["ports", *ports.values(), "--reply-timeout", "0.2"]
    return argv + (SLACK if argv[0] == "doctor" else [])


def test_the_transcripts_are_what_the_commands_print(tmp_path, rig_ports, capsys):
    text = config_text("lab-rig", rig_ports)
    text = re.sub(r"(zero_position = 0 +)# CALIBRATE.*", r"\1", text)
    text = re.sub(r"(length_at_zero_m = \S+ +)# CALIBRATE.*", r"\1", text)
    text = text.replace("reply_timeout_s = 0.034", "reply_timeout_s = 0.2")  # a pty shares the CPU
    config = tmp_path / "my-rig.toml"
    config.write_text(text)
    blocks = transcripts()
    assert {c.split()[1] for c, _ in blocks} >= {"ports", "doctor", "imu", "wheels", "servos"}
    for command, expected in blocks:
        # the wheel board's heartbeat (HEARTBEAT_MS, 250 ms) lapses between two commands, as
        # by hand: twice over, for an emulator thread held up a moment
        time.sleep(2 * wp.PARAM_BY_NAME["HEARTBEAT_MS"].default / 1000.0)
        status = main(argv_for(command, str(config), rig_ports))
        captured = capsys.readouterr()
        assert status == 0, (command, captured.out, captured.err)
        printed = {shape(line) for line in (captured.out + captured.err).splitlines()}
        missing = [line for line in expected if line != "..." and shape(line) not in printed]
        assert not missing, (command, missing, captured.out, captured.err)
