#!/usr/bin/env bash
# The dependency floors as a user gets them: a venv on the oldest supported Python found
# (tools/oldest-python.sh, or $PYTHON_OLDEST), the floors of tools/oldest-constraints.txt,
# `pip install .` (not editable), then from another directory `gyrotens simulate` (the model, the
# CLI with every command, numpy and scipy) and `gyrotens plot` (matplotlib), and an import of the
# modules built on the other floors (pyserial, dynamixel-sdk, filterpy, mcap). `make test` runs it
# beside the computing tests; `make oldest` runs those tests on the same floors.
# Usage: tools/check-floors.sh [VENV]   (default build/venv-floors, made anew each time)
set -euo pipefail
cd "$(dirname "$0")/.."
venv="$(realpath -m "${1:-build/venv-floors}")"
py="${PYTHON_OLDEST:-}"
if [ -z "$py" ] && ! py="$(tools/oldest-python.sh)"; then
    echo "floors: skipped: no Python 3.10 to 3.12 here, and the floors have no wheels for newer"
    exit 0
fi
rm -rf "$venv"
"$py" -m venv "$venv"
# --no-compile: byte-compiling scipy and matplotlib would double the CPU time, and checks nothing
# that importing them below does not.
"$venv/bin/pip" install -q --no-compile -c tools/oldest-constraints.txt .
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"
"$venv/bin/gyrotens" simulate dbar-gyro -o run.npz
"$venv/bin/gyrotens" plot run.npz -o plots --no-animation >/dev/null
"$venv/bin/python" -c "import gyrohost.drivers.imu, gyrohost.drivers.servos, \
gyrohost.drivers.wheelboard, gyrohost.estimator.ekf, gyrohost.run.mcap"
"$venv/bin/python" - <<'PY'
import platform
from importlib.metadata import version

names = ["numpy", "scipy", "matplotlib", "dynamixel-sdk", "filterpy", "mcap"]
floors = ", ".join(f"{name} {version(name)}" for name in names)
print(f"floors: installed and ran on Python {platform.python_version()} with {floors}")
PY
