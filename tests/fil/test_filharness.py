"""The FIL helper fails loudly (never skips) when the harness or the firmware ELF is missing."""

from __future__ import annotations

import filharness
import pytest
from filharness import HarnessError, firmware_elf, parse_kv, require_file

pytestmark = pytest.mark.fil


def test_missing_file_names_path_and_make_command(tmp_path):
    missing = tmp_path / "fil_harness"
    with pytest.raises(HarnessError, match=r"fil_harness.*make -C firmware check"):
        require_file(missing, "FIL harness")


def test_missing_elf_names_directory(tmp_path, monkeypatch):
    monkeypatch.setattr(filharness, "AVR_BUILD", tmp_path / "avr")
    with pytest.raises(HarnessError, match=r"exactly one firmware ELF .*found none"):
        firmware_elf()


def test_parse_stats_line():
    kv = parse_kv("STATS t_s=1.000 steps=1000 rpm=1.5,-2,0,0")
    assert kv == {"tag": "STATS", "t_s": "1.000", "steps": "1000", "rpm": "1.5,-2,0,0"}
