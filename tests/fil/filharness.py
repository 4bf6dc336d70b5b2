"""The FIL suite's view of the simavr harness helper, :mod:`gyrohost.rig.simavr`.

Everything (locating the binaries with a clear error, starting the harness, parsing its ``PTY``,
``STATS`` and ``FINAL`` lines, stdin commands, shutdown) lives in the package, which the
simulated rig also uses for ``--wheel-board simavr``. Only :data:`AVR_BUILD` is looked up here at
call time, so a test can point :func:`firmware_elf` elsewhere. Nothing here builds anything:
``make -C firmware check`` does.
"""

from __future__ import annotations

from pathlib import Path

from gyrohost.rig import simavr
from gyrohost.rig.simavr import (
    FIRMWARE,
    HARNESS,
    REPO_ROOT,
    SELFTEST_ELF,
    Harness,
    HarnessError,
    parse_kv,
    require_file,
    stats_rpm,
)

ROOT = REPO_ROOT
AVR_BUILD = simavr.AVR_BUILD


def firmware_elf() -> Path:
    """The wheel-board firmware ELF in :data:`AVR_BUILD` (exactly one ``*.elf`` expected)."""
    return simavr.firmware_elf(AVR_BUILD)


__all__ = [
    "AVR_BUILD",
    "FIRMWARE",
    "HARNESS",
    "ROOT",
    "SELFTEST_ELF",
    "Harness",
    "HarnessError",
    "firmware_elf",
    "parse_kv",
    "require_file",
    "stats_rpm",
]
