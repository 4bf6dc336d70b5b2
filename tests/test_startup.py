"""``gyrotens --version`` and ``--help`` import nothing heavy (docs/performance.md)."""

import subprocess
import sys

import pytest

HEAVY = ("numpy", "scipy", "matplotlib", "gyrotensegrity")
PROBE = """
import sys
from gyrohost.cli import main
try:
    main([{arg!r}])
except SystemExit:
    pass
print("HEAVY", *sorted(m for m in {heavy!r} if m in sys.modules))
"""


@pytest.mark.parametrize("arg", ["--version", "--help"])
def test_version_and_help_import_no_numpy_scipy_or_the_model(arg):
    out = subprocess.run(
        [sys.executable, "-c", PROBE.format(arg=arg, heavy=HEAVY)],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert "gyrotens" in out
    assert out.splitlines()[-1] == "HEAVY", out
