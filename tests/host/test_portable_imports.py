"""The host runs where pyserial does (Linux, macOS, Windows): no module outside the simulated rig
imports a Unix-only module when it is imported (pyserial picks its own backend per platform),
and the device commands import and refuse a missing port with ``grp`` and ``pwd`` unavailable."""

import ast
import subprocess
import sys
from pathlib import Path

import gyrohost
import gyrotensegrity

UNIX_ONLY = {"grp", "pwd", "fcntl", "termios", "pty"}
SIMULATED_RIG = Path(gyrohost.__file__).parent / "simrig"


def import_time_imports(tree: ast.AST) -> set[str]:
    """Top-level module names imported when the module is (function bodies left out)."""
    found, todo = set(), list(ast.iter_child_nodes(tree))
    while todo:
        node = todo.pop()
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            continue
        if isinstance(node, ast.Import):
            found |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.add(node.module.split(".")[0])
        todo += ast.iter_child_nodes(node)
    return found


def test_no_module_outside_the_simulated_rig_imports_a_unix_only_module():
    offenders = []
    for package in (gyrohost, gyrotensegrity):
        for path in Path(package.__file__).parent.rglob("*.py"):
            if SIMULATED_RIG in path.parents:
                continue
            names = import_time_imports(ast.parse(path.read_text(), str(path))) & UNIX_ONLY
            if names:
                offenders.append(f"{path}: {', '.join(sorted(names))}")
    assert not offenders, offenders


PROBE = """
import sys
sys.modules["grp"] = sys.modules["pwd"] = None  # as on Windows
import gyrohost.commands.wheels, gyrohost.commands.servos, gyrohost.commands.imu
import gyrohost.commands.doctor, gyrohost.commands.ports, gyrohost.commands.run
import gyrohost.bringup.doctor, gyrohost.bringup.wheels, gyrohost.bringup.servo_moves
import gyrohost.bringup.imu_setup, gyrohost.run.sequence
from gyrohost.cli import main
sys.exit(main(["wheels", "spin", "--port", "/nonexistent/tty", "--wheel", "0", "--speed", "1"]))
"""


def test_the_device_commands_import_and_refuse_a_missing_port_without_grp():
    done = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True)
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith("gyrotens wheels: error: --port /nonexistent/tty: no such"), (
        done.stderr
    )


WITHOUT_UNIX = """
import sys, types
for name in ("grp", "pwd", "fcntl", "termios", "pty", "tty"):
    sys.modules[name] = None
serial = types.ModuleType("serial")  # pyserial's POSIX backend needs fcntl and termios
serial.SerialException = type("SerialException", (OSError,), {})
serial.Serial = object
sys.modules["serial"] = serial
import gyrohost.cli, gyrohost.run.sequence, gyrohost.run.connect, gyrohost.run.simulated
import gyrohost.bringup.doctor, gyrohost.bringup.wheels, gyrohost.bringup.servo_moves
import gyrohost.bringup.imu_setup, gyrohost.drivers.wheelboard, gyrohost.drivers.imu
gyrohost.cli.build_parser()
"""


def test_run_doctor_and_the_device_commands_import_without_any_unix_only_module():
    """As on Windows: no grp, pwd, fcntl, termios, pty or tty (pyserial stubbed, as its Windows
    backend stands in there); the simulated rig alone is left out."""
    done = subprocess.run([sys.executable, "-c", WITHOUT_UNIX], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
