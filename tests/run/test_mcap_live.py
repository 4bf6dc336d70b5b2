"""Logs robotics tools open: ``gyrotens run --sim --live`` serves its channels over a Foxglove
WebSocket (a client on localhost receives them), and the run's ``run.mcap``, read back with the
``mcap`` reader, holds one channel per CSV stream with its JSON schema, as many messages as the
CSV has rows, and the 3D scenes; ``gyrotens export LOG --mcap`` makes a whole file from the CSVs
of a run whose MCAP was cut off."""

import json
import re
import subprocess
import sys
import threading

import numpy as np
import pytest
import websockets.sync.client as ws_client
from mcap.exceptions import McapError
from mcap.reader import make_reader
from websockets.exceptions import ConnectionClosed

from gyrohost.cli import main
from gyrohost.config import load_rig_config
from gyrohost.control.schedule import Schedule
from gyrohost.estimator.ekf import Status
from gyrohost.resources import shipped
from gyrohost.run.foxglove import RowJson, z_to
from gyrohost.run.log import format_value, read_meta, read_stream
from gyrohost.run.ticker import status_words
from gyrotensegrity import load_scene

WANTED = {"/imu", "/estimate", "/scene/estimate", "/scene/truth"}


def short_schedule(tmp_path):
    """s13 1 cm shorter in 0.5 s on the sim-rig scene."""
    scene = load_scene(load_rig_config(shipped("config", "sim-rig")).scene_path)
    l0 = next(s.rest_length(0.0) for s in scene.strings if s.name == "s13")
    return Schedule(("s13",), [0.0, 0.5], [[l0], [l0 - 0.01]], "short").save(tmp_path / "s.toml")


def watch(url: str, got: dict) -> None:
    """Subscribe to every channel the server advertises; keep the first payload per topic and
    count messages, until the server closes. A channel created while the client is connected
    is advertised to it a moment before the server records it for the client (foxglove-sdk
    0.30: status "Unknown channel ID"; docs/run.md#the-live-view-gyrotens-run---live): that
    subscription is sent again."""
    topics = {}
    with ws_client.connect(url, subprotocols=["foxglove.sdk.v1"], open_timeout=10) as ws:
        try:
            while True:
                msg = ws.recv(timeout=60)
                if isinstance(msg, str):
                    op = json.loads(msg)
                    if op["op"] == "advertise":
                        subs = [{"id": c["id"], "channelId": c["id"]} for c in op["channels"]]
                        topics.update({c["id"]: c for c in op["channels"]})
                        ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                    unknown = re.fullmatch(r"Unknown channel ID: (\d+)", op.get("message", ""))
                    if unknown:  # advertised before the server could take a subscription: again
                        sub = {"id": int(unknown[1]), "channelId": int(unknown[1])}
                        ws.send(json.dumps({"op": "subscribe", "subscriptions": [sub]}))
                    continue
                assert msg[0] == 1  # message data: opcode, subscription id, log time, payload
                channel = topics[int.from_bytes(msg[1:5], "little")]
                entry = got.setdefault(channel["topic"], {"count": 0, "channel": channel})
                entry["count"] += 1
                entry.setdefault("first", json.loads(msg[13:]))
        except (ConnectionClosed, TimeoutError):
            return


@pytest.fixture(scope="module")
def live_run(tmp_path_factory):
    """One short ``run --sim --live``: its log folder and what a WebSocket client received."""
    tmp = tmp_path_factory.mktemp("live")
    log = tmp / "log"
    cmd = [sys.executable, "-m", "gyrohost", "run", "--sim", "--live", "--live-port", "0"]
    cmd += ["--schedule", str(short_schedule(tmp)), "-o", str(log)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    got, watcher = {}, None
    try:
        for line in proc.stdout:
            match = re.match(r"live: (ws://127\.0\.0\.1:\d+) ", line)
            if match:
                watcher = threading.Thread(target=watch, args=(match[1], got), daemon=True)
                watcher.start()
                break
        out, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert watcher is not None and proc.returncode == 0, err
    watcher.join(timeout=30)
    return log, got


def test_a_websocket_client_receives_the_run_live(live_run):
    _, got = live_run
    assert WANTED <= set(got), sorted(got)
    imu = got["/imu"]
    assert imu["channel"]["encoding"] == "json"
    assert imu["channel"]["schemaEncoding"] == "jsonschema"
    assert set(json.loads(imu["channel"]["schema"])["properties"]) == set(imu["first"])
    assert {"t_s", "omega_x_rad_s", "roll_rad"} <= set(imu["first"])
    assert imu["count"] > 50  # 100 Hz for a few seconds, from the first subscription on
    entity = got["/scene/estimate"]["first"]["entities"][0]
    assert got["/scene/estimate"]["channel"]["schemaName"] == "foxglove.SceneUpdate"
    assert len(entity["lines"][0]["points"]) == 8 and len(entity["cylinders"]) == 4


def test_the_run_mcap_holds_every_csv_row_with_schemas_and_scenes(live_run):
    log, _ = live_run
    check_mcap(log / "run.mcap", log)


def test_export_rebuilds_a_cut_off_mcap_from_the_csv_streams(live_run, tmp_path, capsys):
    log, _ = live_run
    whole = (log / "run.mcap").read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(whole[: len(whole) // 2])  # as a killed run leaves it: no summary, no footer
    with pytest.raises(McapError), open(cut, "rb") as f:  # no footer to find
        make_reader(f).get_summary()
    out = tmp_path / "exported.mcap"
    assert main(["export", str(log), "--mcap", "-o", str(out)]) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    check_mcap(out, log)
    with open(out, "rb") as f:
        times = [m.log_time for _, _, m in make_reader(f).iter_messages()]
    assert times == sorted(times)  # rows of every stream in time order
    assert main(["export", str(tmp_path), "--mcap"]) == 2
    assert "not a log folder" in capsys.readouterr().err


def check_mcap(path, log) -> None:
    """``path`` has one channel per stream of ``log`` with its columns' JSON schema and one
    message per CSV row, and 3D scenes of the estimate and the truth."""
    meta = read_meta(log)
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        counts = summary.statistics.channel_message_counts
        channels = {c.topic: c for c in summary.channels.values()}
        for name in meta["streams"]:
            channel = channels[f"/{name}"]
            schema = summary.schemas[channel.schema_id]
            assert (schema.encoding, channel.message_encoding) == ("jsonschema", "json")
            columns = list(json.loads(schema.data)["properties"])
            assert columns == meta["streams"][name]["columns"], name
            assert counts.get(channel.id, 0) == len(read_stream(log, name)), name
        for topic in ("/scene/estimate", "/scene/truth"):
            channel = channels[topic]
            assert summary.schemas[channel.schema_id].name == "foxglove.SceneUpdate"
            assert counts[channel.id] > 10
        decoded = 0
        for _, channel, message in reader.iter_messages(topics=["/scene/truth", "/wheels"]):
            body = json.loads(message.data)
            if channel.topic == "/wheels":
                assert body["t_s"] is not None and len(body) == len(
                    meta["streams"]["wheels"]["columns"]
                )
            else:
                entity = body["entities"][0]
                assert entity["frame_id"] == "world" and len(entity["cylinders"]) == 4
            decoded += 1
        assert decoded == counts[channels["/scene/truth"].id] + counts[channels["/wheels"].id]


def test_status_words_name_the_estimator_bits():
    assert status_words(Status(0)) == "ok"
    both = Status.WHEELS_TIMEOUT | Status.IMU_RATE_REJECTED
    assert status_words(both) == "WHEELS_TIMEOUT|IMU_RATE_REJECTED"


@pytest.mark.parametrize(
    "direction", [(0, 0, 1), (0, 0, -2), (1, 0, 0), (0.3, -0.4, 0.2), (-1e-3, 2e-3, -1)]
)
def test_a_wheel_cylinder_axis_lies_along_its_bar(direction):
    q = z_to(direction)
    x, y, z, w = q["x"], q["y"], q["z"], q["w"]
    # the rotated z axis: third column of the quaternion's rotation matrix
    axis = np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
    assert np.allclose(axis, np.array(direction) / np.linalg.norm(direction), atol=1e-9)
    assert x * x + y * y + z * z + w * w == pytest.approx(1.0)


def test_a_row_message_is_the_csv_row_as_json():
    columns = ("t_s", "x_m", "gap_m", "far_m", "seq", "ok", "phase")
    values = (np.float64(0.1), -1.0 / 3.0, np.nan, -np.inf, np.int64(7), True, "schedule")
    rows = RowJson(columns, ("phase",))
    made_here = json.loads(rows.json(values))
    from_csv = json.loads(rows.json(values, [format_value(v) for v in values]))
    assert made_here == from_csv == {
        "t_s": 0.1, "x_m": -1.0 / 3.0, "gap_m": None, "far_m": None, "seq": 7, "ok": 1,
        "phase": "schedule",
    }  # fmt: skip
    assert from_csv["x_m"] == -1.0 / 3.0  # bit for bit: the shortest exact text
