"""The FIL suite's view of the simavr harness helper, :mod:`gyrohost.simrig.simavr`.

Everything (locating the binaries with a clear error, starting the harness, parsing its ``PTY``,
``STATS`` and ``FINAL`` lines, stdin commands, shutdown) lives in the package, which the
simulated rig also uses for ``--wheel-board simavr``. The suite tests this checkout's firmware:
the binaries are those of ``firmware/build`` (``tests/conftest.py`` points
``GYROTENS_FIRMWARE_BUILD`` there too). Only :data:`AVR_BUILD` is looked up here at call time, so
a test can point :func:`firmware_elf` elsewhere. Nothing here builds anything:
``make -C firmware check`` does.
"""

from __future__ import annotations

import os
from pathlib import Path

from gyrohost.simrig import simavr
from gyrohost.simrig.errors import HarnessError
from gyrohost.simrig.simavr import Harness, parse_kv, require_file, stats_rpm

ROOT = Path(__file__).resolve().parents[2]
FIRMWARE = ROOT / "firmware"
BUILD = FIRMWARE / "build"
HARNESS = BUILD / "sim" / "fil_harness"
SELFTEST_ELF = BUILD / "sim" / "selftest.elf"
AVR_BUILD = BUILD / "avr"

# The harness's default binary comes from this setting; fil_bench.py runs without the conftest.
os.environ.setdefault(simavr.FIRMWARE_BUILD_ENV, str(BUILD))


set_offsets = simavr.set_enc_offsets
"""Every wheel's ENC_OFFSET for the harness's default ``--elec-offset 0``: a blank EEPROM leaves
the offsets unset, which refuses closed-loop setpoints (OFFSET_UNCALIBRATED)."""


def firmware_elf() -> Path:
    """The wheel-board firmware ELF in :data:`AVR_BUILD` (exactly one ``*.elf`` expected)."""
    return simavr.firmware_elf(AVR_BUILD)


__all__ = [
    "AVR_BUILD",
    "BUILD",
    "FIRMWARE",
    "HARNESS",
    "ROOT",
    "SELFTEST_ELF",
    "Harness",
    "set_offsets",
    "HarnessError",
    "firmware_elf",
    "parse_kv",
    "require_file",
    "stats_rpm",
]
