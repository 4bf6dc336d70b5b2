#!/usr/bin/env bash
# Print the path of the oldest supported Python that runs here, for the floors check
# (tools/check-floors.sh) and `make oldest`: Python 3.10 on PATH or pyenv's (a pyenv shim exists
# for every installed version but refuses to run one that is not selected, so each candidate is
# run, not only looked up), else 3.11 or 3.12 with a line on stderr saying so. Nothing newer: the
# floors' numpy 1.26 and scipy 1.11 have no wheels past 3.12. Exit 1 when none runs.
set -euo pipefail
for minor in 10 11 12; do
    candidates=("python3.$minor")
    if command -v pyenv >/dev/null; then
        candidates+=("$(pyenv root)"/versions/3."$minor".*/bin/python3."$minor")
    fi
    for py in "${candidates[@]}"; do
        # ensurepip: Debian ships a Python's venv support in a package of its own.
        if "$py" -c "import ensurepip" 2>/dev/null; then
            [ "$minor" -eq 10 ] || echo "no Python 3.10 here (PATH, pyenv): using 3.$minor" >&2
            command -v "$py"
            exit 0
        fi
    done
done
echo "no Python 3.10 to 3.12 with venv support here (PATH, pyenv)" >&2
exit 1
