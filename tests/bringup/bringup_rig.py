"""Rig configurations pointing at the simulated rig's ptys, for the bring-up tests."""

import re

from gyrohost.resources import shipped


def config_text(name: str, ports: dict[str, str], **replace: str) -> str:
    """The shipped configuration ``name`` with its three ports set to ``ports`` (device name ->
    path) and each ``old=new`` text of ``replace`` (keys: any label) swapped."""
    text = shipped("config", name).read_text()
    for table, device in (("imu", "imu"), ("servos", "servos"), ("wheelboard", "wheels")):
        text = re.sub(
            rf"(\[{table}\]\n(?:.*\n)*?port = )\"[^\"]*\"", rf'\1"{ports[device]}"', text, count=1
        )
    for old, new in replace.values():
        assert old in text, old
        text = text.replace(old, new)
    return text
