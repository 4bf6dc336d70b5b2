"""Input files that are not UTF-8 TOML: a binary file, another encoding, a byte-order mark.

Every loader (scene, rig configuration, schedule, estimator settings) reads through
``gyrotensegrity.textfile.read_text``: a bad file is one line naming it, a BOM is dropped.
"""

import pytest

from gyrohost.cli import main
from gyrohost.config import ConfigError, load_rig_config
from gyrohost.control.errors import ScheduleError
from gyrohost.control.schedule import load_schedule
from gyrohost.estimator.config import load_config
from gyrohost.estimator.errors import EstimatorConfigError
from gyrohost.resources import shipped
from gyrotensegrity import SceneError, load_scene

ESTIMATOR = b"[estimator]\nimu_period_s = 0.02\n"
LOADERS = {
    "scene": (load_scene, SceneError, shipped("scene", "dbar-gyro").read_bytes()),
    "config": (load_rig_config, ConfigError, shipped("config", "sim-rig").read_bytes()),
    "schedule": (load_schedule, ScheduleError, shipped("schedule", "prism-s7").read_bytes()),
    "estimator": (load_config, EstimatorConfigError, ESTIMATOR),
}
BINARY = bytes(range(256)) * 4
LATIN1 = "# Länge\n".encode("latin-1")


@pytest.mark.parametrize("kind", LOADERS)
def test_a_bom_is_dropped(kind, tmp_path):
    load, _, text = LOADERS[kind]
    plain, bom = tmp_path / "plain.toml", tmp_path / "bom.toml"
    plain.write_bytes(text)
    bom.write_bytes(b"\xef\xbb\xbf" + text)
    assert repr(load(bom)).replace("bom.toml", "") == repr(load(plain)).replace("plain.toml", "")


@pytest.mark.parametrize("kind", LOADERS)
@pytest.mark.parametrize(
    ("content", "what"),
    [
        (BINARY, "a binary file (NUL byte at offset 0)"),
        (b"\x89PNG\r\n\x1a\n" + bytes(range(1, 256)), "not UTF-8 text (byte 0x89 at offset 0)"),
        (LATIN1, "not UTF-8 text (byte 0xe4 at offset 3)"),
    ],
)
def test_not_utf8_is_one_line_naming_the_file(kind, content, what, tmp_path):
    load, error, text = LOADERS[kind]
    path = tmp_path / "bad.toml"
    path.write_bytes(content if content is not LATIN1 else content + text)
    with pytest.raises(error) as info:
        load(path)
    message = str(info.value)
    assert message.startswith(f"{path}: {what}")
    assert "\n" not in message


@pytest.mark.parametrize("option", ["--config", "--scene", "--schedule", "--estimator"])
def test_run_refuses_a_binary_input_before_anything_moves(option, tmp_path, capsys):
    path = tmp_path / "binary.toml"
    path.write_bytes(BINARY)
    out = tmp_path / "log"
    assert main(["run", "--sim", option, str(path), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    what = "a binary file (NUL byte at offset 0), not UTF-8 text"
    assert err == f"gyrotens run: error: {path}: {what}\n"
    assert not out.exists()
