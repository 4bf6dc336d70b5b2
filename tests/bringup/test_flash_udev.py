"""``make flash`` flashes the ELF the firmware-in-the-loop tests run, with avrdude; the udev
rules give the names the lab-rig template uses."""

import re
import subprocess
from pathlib import Path

import pytest

from gyrohost.config import load_rig_config
from gyrohost.resources import shipped

ROOT = Path(__file__).resolve().parents[2]


def make(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["make", *args], cwd=ROOT, capture_output=True, text=True)


def test_make_flash_builds_then_writes_the_tested_elf_with_avrdude():
    done = make("-n", "flash", "PORT=/dev/ttyACM0")
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    avrdude = [line for line in lines if line.startswith("avrdude ")]
    assert avrdude == [
        "avrdude -p atmega2560 -c stk500v2 -P /dev/ttyACM0 -b 115200 -D "
        "-U flash:w:firmware/build/avr/wheelboard.elf:e"
    ]
    build = lines.index("make --no-print-directory -C firmware avr")
    assert build < lines.index(avrdude[0])  # built (or found up to date) first, size report too
    # the brown-out fuse checked before anything is written
    assert lines.index("tools/check-bod.sh /dev/ttyACM0 stk500v2") < lines.index(avrdude[0])
    assert any("build/avr/wheelboard.elf" in line for line in lines[build:])
    # the ELF the FIL tests run (tests/fil/filharness.py: firmware/build/avr, one *.elf)
    assert "ELF         := $(AVR_OUT)/wheelboard.elf" in (ROOT / "firmware/Makefile").read_text()


def test_make_flash_without_a_port_says_how_to_give_one():
    done = make("flash")
    assert done.returncode != 0
    assert "usage: make flash PORT=/dev/ttyACM0" in done.stderr


def test_ensure_debs_installs_avrdude_for_all():
    script = (ROOT / "tools/ensure-debs.sh").read_text()
    all_line = re.search(r"all\) packages=\(([^)]*)\)", script).group(1)
    assert "avrdude" in all_line.split()


def test_udev_rules_name_the_ports_of_the_lab_rig_template():
    rules = (ROOT / "tools/udev/99-gyrotens.rules").read_text()
    config = load_rig_config(shipped("config", "lab-rig"))
    for port, ids in (
        (config.wheelboard.port, [("2341", "0042"), ("1a86", "7523")]),
        (config.servos.port, [("0403", "6014")]),
    ):
        name = port.removeprefix("/dev/")
        for vid, pid in ids:
            rule = f'ATTRS{{idVendor}}=="{vid}", ATTRS{{idProduct}}=="{pid}", SYMLINK+="{name}"'
            assert rule in rules
    assert 'ATTRS{idProduct}=="6014", ATTR{latency_timer}="1"' in rules
    assert config.imu.port == "/dev/rfcomm0" and 'KERNEL=="rfcomm0"' in rules


def check_bod(tmp_path: Path, efuse: str, status: int = 0) -> subprocess.CompletedProcess:
    """tools/check-bod.sh against a fake avrdude that prints ``efuse`` and exits ``status``."""
    fake = tmp_path / "avrdude"
    fake.write_text(f"#!/bin/sh\necho '{efuse}'\nexit {status}\n")
    fake.chmod(0o755)
    env = {"PATH": f"{tmp_path}:/usr/bin:/bin"}
    return subprocess.run(
        [str(ROOT / "tools/check-bod.sh"), "/dev/ttyACM0", "stk500v2"],
        capture_output=True,
        text=True,
        env=env,
    )


@pytest.mark.parametrize("efuse", ["0xfc", "0x04", "0xFC"])
def test_check_bod_passes_a_board_at_4_3_v(tmp_path, efuse):
    done = check_bod(tmp_path, efuse)
    assert done.returncode == 0, done.stderr


@pytest.mark.parametrize("efuse", ["0xfd", "0xff", "0x05", "0xfe"])
def test_check_bod_refuses_another_level_and_says_how_to_set_it(tmp_path, efuse):
    done = check_bod(tmp_path, efuse)
    assert done.returncode == 1
    assert f"extended fuse {efuse}: its brown-out detector is not at 4.3 V" in done.stderr
    assert "-U efuse:w:0xFC:m" in done.stderr


def test_check_bod_refuses_when_the_fuse_cannot_be_read(tmp_path):
    done = check_bod(tmp_path, "", status=1)
    assert done.returncode == 1
    assert "cannot read the extended fuse of the board on /dev/ttyACM0" in done.stderr
    assert check_bod(tmp_path, "garbage").returncode == 1
