"""The offline firmware build compiles exactly the sources that platformio.ini names.

platformio.ini is what users build with (``pio run -e megaatmega2560``); firmware/Makefile is the
offline path on Debian's avr-gcc. This test derives the Mega source set from the PlatformIO
configuration (src_dir filtered by build_src_filter, plus the libraries of lib_dir that the
library dependency finder reaches from the sources' #includes) and compares it with
``make -C firmware print-sources``.
"""

import fnmatch
import json
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PIO = ROOT / ".venv" / "bin" / "pio"
ENV = "env:megaatmega2560"
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.MULTILINE)


def pio_config() -> dict:
    if not PIO.exists():
        pytest.fail(f"{PIO} missing: run `make setup` (platformio is a dev dependency)")
    out = subprocess.run(
        [str(PIO), "project", "config", "--json-output"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    return {section: dict(items) for section, items in json.loads(out)}


def make_print(target: str) -> str:
    """Output of ``make -s -C firmware <target>`` (print-sources, print-flags)."""
    return subprocess.run(
        ["make", "-s", "-C", "firmware", target],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    ).stdout


def filter_sources(src_dir: Path, filters: list[str]) -> set[Path]:
    """Apply PlatformIO's ordered +<glob>/-<glob> filter to the C/C++ files of src_dir."""
    files = [p for p in src_dir.rglob("*") if p.suffix in {".c", ".cpp", ".S"}]
    chosen: set[Path] = set()
    for expr in " ".join(filters).split():
        m = re.fullmatch(r"([+-])<(.+)>", expr)
        assert m, f"platformio.ini build_src_filter: cannot parse {expr!r}"
        sign, pattern = m.groups()
        hits = {p for p in files if fnmatch.fnmatch(p.relative_to(src_dir).as_posix(), pattern)}
        chosen = chosen | hits if sign == "+" else chosen - hits
    return chosen


def reached_libraries(sources: set[Path], lib_dir: Path) -> set[Path]:
    """Library folders whose headers are reached from the sources, following includes."""
    headers = {h.name: h.parent for h in lib_dir.glob("*/*.h")}
    libs: set[Path] = set()
    todo = list(sources)
    seen: set[Path] = set()
    while todo:
        f = todo.pop()
        if f in seen:
            continue
        seen.add(f)
        for name in INCLUDE.findall(f.read_text()):
            lib = headers.get(name)
            if lib is not None and lib not in libs:
                libs.add(lib)
                todo.extend(lib.glob("*.h"))
                todo.extend(lib.glob("*.cpp"))
    return libs


def test_offline_build_compiles_the_platformio_sources():
    cfg = pio_config()
    src_dir = Path(cfg["platformio"]["src_dir"])
    lib_dir = Path(cfg["platformio"]["lib_dir"])
    assert src_dir == ROOT / "firmware" / "src"
    srcs = filter_sources(src_dir, cfg[ENV].get("build_src_filter", ["+<*>"]))
    assert srcs, "platformio.ini selects no source file"
    libs = reached_libraries(srcs, lib_dir)
    pio_set = srcs | {p for lib in libs for p in lib.glob("*.cpp")}

    out = make_print("print-sources")
    make_set = {ROOT / "firmware" / line for line in out.split()}
    rel = lambda s: sorted(p.relative_to(ROOT).as_posix() for p in s)  # noqa: E731
    assert rel(make_set) == rel(pio_set), (
        f"only in Makefile: {rel(make_set - pio_set)}; only in platformio.ini: "
        f"{rel(pio_set - make_set)}"
    )


def test_platformio_envs_are_the_documented_ones():
    cfg = pio_config()
    mega = cfg[ENV]
    assert mega["platform"] == "atmelavr"
    assert mega["board"] == "megaatmega2560"
    assert "framework" not in mega, "the board layer is bare avr-libc; no Arduino core"
    assert str(mega["board_build.f_cpu"]).startswith("16000000")
    native = cfg["env:native"]
    assert native["platform"] == "native"
    assert native["test_framework"] == "googletest"
    assert Path(cfg["platformio"]["test_dir"]) == ROOT / "firmware" / "test"


# PlatformIO's bare atmelavr flags (platform-atmelavr, builder/frameworks/_bare.py: CCFLAGS with
# the machine flag, CXXFLAGS, CPPDEFINES F_CPU; LINKFLAGS and LIBS), as `pio run` passes them.
PIO_BARE_COMPILE = (
    "-mmcu=atmega2560 -Os -Wall -ffunction-sections -fdata-sections -flto "
    "-Wno-error=narrowing -fno-exceptions -fno-threadsafe-statics -fpermissive -std=gnu++11"
).split()
PIO_BARE_LINK = "-mmcu=atmega2560 -Os -Wl,--gc-sections -flto -fuse-linker-plugin -lm".split()


def test_offline_build_uses_the_platformio_flags():
    """One ELF: the Makefile's flags are PlatformIO's after platformio.ini's unflags and flags."""
    mega = pio_config()[ENV]
    unflags = set(" ".join(mega.get("build_unflags", [])).split())
    extra = " ".join(mega.get("build_flags", [])).split()
    f_cpu = str(mega["board_build.f_cpu"])
    pio_compile = {f for f in PIO_BARE_COMPILE if f not in unflags} | set(extra)
    pio_compile.add(f"-DF_CPU={f_cpu}")
    pio_link = {f for f in PIO_BARE_LINK if f not in unflags}
    out = make_print("print-flags")
    lines = dict(line.split(" ", 1) for line in out.splitlines())
    make_compile, make_link = set(lines["compile"].split()), set(lines["link"].split())
    assert make_compile == pio_compile, (
        f"only in Makefile: {sorted(make_compile - pio_compile)}; "
        f"only in platformio.ini: {sorted(pio_compile - make_compile)}"
    )
    assert make_link == pio_link, (
        f"only in Makefile: {sorted(make_link - pio_link)}; "
        f"only in platformio.ini: {sorted(pio_link - make_link)}"
    )
    assert "-flto" not in make_compile, "LTO off in both (platformio.ini build_unflags)"
