#!/bin/sh
# Control-step cycle figures of the wheel-board firmware in the FIL harness (all four wheels at
# 715 rpm), then the 0 -> 715 rpm step response. Needs `make -C firmware check` first.
# usage: firmware/sim/cycles.sh [--seconds N]
set -eu
root=$(cd "$(dirname "$0")/../.." && pwd)
py="$root/.venv/bin/python"
[ -x "$py" ] || py=python3
export PYTHONPATH="$root/tests${PYTHONPATH:+:$PYTHONPATH}"  # control_beat.py
"$py" "$root/tests/fil/fil_bench.py" cycles "$@"
echo
"$py" "$root/tests/fil/fil_bench.py" step
echo
"$py" "$root/tests/fil/fil_bench.py" step --accel 10000
