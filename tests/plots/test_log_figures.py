"""What the run figures draw, checked on the data they draw (no image comparison): a short run
on the simulated rig for the bands, innovations and line styles, synthetic logs for the
attitude across a pitch of -90° and for a log written before the standard deviations were."""

import numpy as np
import pytest
from scipy.stats import chi2, norm
from sim_run import sim_run_log

from gyrohost.estimator.config import EstimatorConfig
from gyrohost.estimator.imu_model import ImuGeometry
from gyrohost.geometry import euler_zyx, rotation_zyx
from gyrohost.plots.log import (
    NO_BAND,
    figure_attitude,
    figure_body_attitude,
    figure_innovations,
    figure_node_z,
    figure_nodes,
    figure_wheels,
    plot_log,
)
from gyrohost.plots.run_data import RunData, attitude_lines, body_lines, sensor_axes
from gyrohost.plots.styles import style
from gyrohost.resources import shipped
from gyrohost.run.log import read_meta
from gyrohost.run.streams import BODY_ATTITUDE
from gyrohost.sil.synthetic import write_log
from gyrotensegrity import Model, attitude_of, load_scene

SCHEDULE = """[schedule]
name = "figures"
t_s = [0.0, 1.0]

[rest_length_m]
s13 = [0.43105229381822, 0.40]
"""


@pytest.fixture(scope="module")
def log(tmp_path_factory):
    """A short ``gyrotens run --sim`` of the D-bar (its log folder)."""
    return sim_run_log(tmp_path_factory.mktemp("figures"), SCHEDULE)


@pytest.fixture(scope="module")
def data(log):
    return RunData(log)


def drawn_band(collection, t):
    """(lower, upper) of a ``fill_between`` over times ``t``, from its polygon: its start,
    the lower edge forward, the end again, the upper edge back, closed."""
    v = collection.get_paths()[0].vertices
    n = len(t)
    lower, upper = v[1 : n + 1], v[n + 2 : 2 * n + 2][::-1]
    assert np.array_equal(lower[:, 0], t) and np.array_equal(upper[:, 0], t)
    return lower[:, 1], upper[:, 1]


def test_node_bands_are_twice_the_logged_standard_deviation_of_the_state(data):
    # the D-bar's node coordinates are each one filter coordinate times a constant (a row of
    # U2 with one entry), so their standard deviation is that constant times the one logged
    # with the state in the estimate stream, row by row
    model = Model(load_scene(shipped("scene", "dbar-gyro")))
    U2 = model.U2.toarray()
    assert np.all(np.count_nonzero(U2, axis=1) == 1)
    nodes, est = data.get("nodes"), data.get("estimate")
    assert np.array_equal(nodes["t_s"], est["t_s"])
    fig = figure_node_z(data)
    for ax, node in zip(fig.axes, ("n1", "n2", "n3", "n4"), strict=True):
        i = model.structure.node_names.index(node)
        j = int(np.flatnonzero(U2[i])[0])
        sigma = abs(U2[i, j]) * est[f"std_q_z{j}_m"]
        assert np.allclose(nodes[f"std_{node}_z_m"], sigma, rtol=1e-6, atol=1e-12)
        lower, upper = drawn_band(ax.collections[0], nodes["t_s"])
        assert np.allclose(upper - lower, 100 * 4 * sigma, rtol=1e-6, atol=1e-9)  # cm, ±2σ
        assert np.allclose(0.5 * (upper + lower), 100 * nodes[f"{node}_z_m"])
    assert not [t for t in fig.texts if t.get_text() == NO_BAND]


def test_tilt_band_is_twice_the_logged_tilt_sigma(data):
    nodes = data.get("nodes")
    assert np.all(nodes["std_tilt_rad"] > 0) and np.all(np.isfinite(nodes["std_tilt_rad"]))
    fig = figure_attitude(data)
    lower, upper = drawn_band(fig.axes[0].collections[0], nodes["t_s"])
    assert np.allclose(upper - lower, np.degrees(4 * nodes["std_tilt_rad"]), rtol=1e-6)
    (estimate, truth) = fig.axes[0].get_lines()[:2]  # unwrapped: no jump where it passes 180
    assert np.allclose(estimate.get_ydata(), np.degrees(np.unwrap(nodes["tilt_rad"])))
    assert np.allclose(truth.get_ydata(), np.degrees(np.unwrap(data.get("truth")["tilt_rad"])))


def test_normalised_innovations_are_innovation_over_its_standard_deviation(log, data):
    fig = figure_innovations(data)
    sources = ["imu_rate", "imu_accel", "imu_angle", "wheels", "servos"]
    assert [ax.get_ylabel().split("\n")[0] for ax in fig.axes] == sources
    for ax, source in zip(fig.axes, sources, strict=True):
        raw = np.genfromtxt(log / f"innov_{source}.csv", delimiter=",", names=True)
        ok = raw["accepted"] == 1
        comps = [c[2:] for c in raw.dtype.names if c.startswith("y_")]
        drawn = {line.get_label(): line for line in ax.get_lines()}
        for c in comps:
            expected = raw[f"y_{c}"][ok] / np.sqrt(raw[f"var_{c}"][ok])
            assert np.allclose(drawn[c].get_ydata(), expected), (source, c)
        (span,) = [p for p in ax.patches if p.get_label() == "95 % (±1.96)"]
        z95 = norm.ppf(0.975)
        assert np.isclose(span.get_y(), -z95) and np.isclose(span.get_y() + span.get_height(), z95)
        k = len(comps)
        lo, hi = chi2.ppf([0.025, 0.975], k * len(raw)) / len(raw)
        title = ax.get_legend().get_title().get_text()
        assert f"mean NIS {np.mean(raw['nis']):.2f} (dof {k})" in title, title
        assert f"95 % [{lo:.2f}, {hi:.2f}]" in title and f"{len(raw)} samples" in title
        assert f"{int(np.sum(~ok))} rejected" in title


def test_wheels_and_nodes_that_coincide_are_drawn_differently(data):
    # wheels 0 and 3 (and 1 and 2) spin alike: dash pattern and marker tell them apart, and
    # the markers sit at different samples, so both show where the lines coincide
    fig = figure_wheels(data)
    lines = {ln.get_label(): ln for ln in fig.axes[0].get_lines()}
    for a, b in ((0, 3), (1, 2)):
        la, lb = lines[f"wheel {a} measured"], lines[f"wheel {b} measured"]
        assert la.get_marker() != lb.get_marker()
        assert la.get_markevery() != lb.get_markevery()
        assert style(a, len(data.get("wheels")))["ls"] != style(b, len(data.get("wheels")))["ls"]
    # nodes on top of each other (n2 and n4 at x = 0): every line its own marker, the truth's
    # hollow, the estimates' dash patterns their own
    fig = figure_nodes(data)
    drawn = [ln for ln in fig.axes[0].get_lines() if not ln.get_label().startswith("_")]
    assert len(drawn) == 8
    assert len({(ln.get_marker(), ln.get_markerfacecolor() == "none") for ln in drawn}) == 8
    assert len({str(style(i, 100)["ls"]) for i in range(4)}) == 4


def test_a_log_without_standard_deviations_plots_without_bands_and_says_so(data, tmp_path):
    nodes = data.get("nodes")
    old = [c for c in nodes.dtype.names if not c.startswith("std_")]
    write_log(
        tmp_path / "old",
        {"nodes": nodes[old], "truth": data.get("truth")},
        shipped("scene", "dbar-gyro"),
        {"estimator": read_meta(data.folder)["estimator"]},
    )
    old_data = RunData(tmp_path / "old")
    for figure in (figure_node_z, figure_nodes, figure_attitude):
        fig = figure(old_data)
        assert NO_BAND in [t.get_text() for t in fig.texts], figure.__name__
        assert not any(ax.collections for ax in fig.axes), figure.__name__
    # node figures, the IMU's attitude and the body frame's (the scene has an [attitude])
    assert len(plot_log(tmp_path / "old", tmp_path / "plots")) == 4


def _pitch_through_minus_90(n=201):
    """Sensor axes turned about y from level through pitch -90° to -150°, with a slow yaw, and
    their Z-Y-X angles (roll and yaw flip by 180° at -90°)."""
    angle = np.linspace(0.0, np.radians(150.0), n)
    yaw = np.linspace(0.0, np.radians(20.0), n)
    R = [
        rotation_zyx(0.0, 0.0, y) @ rotation_zyx(0.0, -a, 0.0)
        for a, y in zip(angle, yaw, strict=True)
    ]
    return angle, np.array([euler_zyx(r) for r in R])


def test_attitude_has_no_jump_across_a_pitch_of_minus_90_degrees(tmp_path):
    angle, euler = _pitch_through_minus_90()
    t = np.linspace(0.0, 2.0, len(angle))
    assert np.max(np.abs(np.diff(np.degrees(euler[:, 0])))) > 170.0  # roll flips in Z-Y-X
    names = ["t_s", "roll_rad", "pitch_rad", "yaw_rad"]
    rows = np.empty(len(t), dtype=[(c, "f8") for c in names])
    rows["t_s"] = t
    rows["roll_rad"], rows["pitch_rad"], rows["yaw_rad"] = euler.T
    write_log(tmp_path / "log", {"imu": rows, "estimate": rows}, shipped("scene", "prism-gyro"))
    fig = figure_attitude(RunData(tmp_path / "log"))
    tilt_ax, heading_ax = fig.axes
    for ax in (tilt_ax, heading_ax):
        for line in ax.get_lines():
            if line.get_label().startswith("_"):
                continue  # the schedule's marker
            assert np.max(np.abs(np.diff(line.get_ydata()))) < 2.0, (ax.get_ylabel(), line)
    lines = attitude_lines(RunData(tmp_path / "log"))
    _, tilt, heading = lines["estimate"]
    # a turn about the level y axis after a yaw: tilt from the vertical is the turn's angle,
    # the twist about the sensor z axis is the yaw
    assert np.allclose(tilt, angle, atol=1e-9)
    assert np.allclose(heading, np.linspace(0.0, np.radians(20.0), len(angle)), atol=1e-9)


def test_truth_sensor_axes_are_attached_as_the_estimator_attaches_them():
    model = Model(load_scene(shipped("scene", "dbar-gyro")))
    config = EstimatorConfig(
        imu_frame_nodes=("n1", "n3", "n2"), imu_mounting_rpy_rad=(0.1, -0.2, 0.3)
    )
    rng = np.random.default_rng(2)
    N = model.structure.N0[None] + 0.05 * rng.normal(size=(6, *model.structure.N0.shape))
    expected, _ = ImuGeometry(model, config).frame(N, np.zeros_like(N))
    a, b, c = (N[:, :, model.structure.primary[n]] for n in config.imu_frame_nodes)
    assert np.allclose(sensor_axes(a, b, c, config.imu_mounting_rpy_rad), expected, atol=1e-12)


def test_plane_tilt_and_its_band_are_unwrapped_across_180_degrees(tmp_path):
    t = np.linspace(0.0, 1.0, 101)
    turned = np.linspace(np.radians(170.0), np.radians(190.0), len(t))  # through +-180 deg
    rows = np.empty(len(t), dtype=[(c, "f8") for c in ("t_s", "tilt_rad", "std_tilt_rad")])
    rows["t_s"], rows["std_tilt_rad"] = t, 0.01
    rows["tilt_rad"] = np.angle(np.exp(1j * turned))  # as logged: in (-pi, pi]
    assert np.max(np.abs(np.diff(rows["tilt_rad"]))) > np.pi
    write_log(tmp_path / "log", {"nodes": rows}, shipped("scene", "dbar-gyro"))
    ax = figure_attitude(RunData(tmp_path / "log")).axes[0]
    (line,) = [ln for ln in ax.get_lines() if ln.get_label() == "estimate ±2σ"]
    assert np.allclose(line.get_ydata(), np.degrees(turned))
    lower, upper = drawn_band(ax.collections[0], t)
    assert np.allclose(lower, np.degrees(turned - 0.02)) and np.allclose(
        upper, np.degrees(turned + 0.02)
    )


def test_body_attitude_is_drawn_unwrapped_with_its_turn_from_the_start(tmp_path):
    """The D-bar turned about its frame's z axis (yaw) through +-180 degrees: yaw drawn without
    the jump the logged angle has, and the turn from the start climbing to pi and back."""
    scene = load_scene(shipped("scene", "dbar-gyro"))
    yaw = np.linspace(0.0, np.radians(300.0), 121)
    N = np.stack([rotation_zyx(0.0, 0.0, a) @ scene.positions for a in yaw])
    att = attitude_of(scene, N)
    rows = np.empty(len(yaw), dtype=[(c, "f8") for c in ("t_s", *BODY_ATTITUDE)])
    rows["t_s"] = np.linspace(0.0, 3.0, len(yaw))
    for k, c in enumerate(BODY_ATTITUDE):
        rows[c] = np.column_stack([att.quaternion, att.rpy_rad])[:, k]
    assert np.max(np.abs(np.diff(rows["body_yaw_rad"]))) > np.pi  # as logged: wrapped
    write_log(tmp_path / "log", {"nodes": rows, "truth": rows}, shipped("scene", "dbar-gyro"))
    data = RunData(tmp_path / "log")
    assert data.body
    line = body_lines(data)["estimate"]
    assert np.allclose(line.rpy_rad[:, 2], yaw, atol=1e-9)
    assert np.allclose(line.rpy_rad[:, :2], 0.0, atol=1e-9)
    assert np.allclose(line.turn_rad, np.minimum(yaw, 2 * np.pi - yaw), atol=1e-6)
    fig = figure_body_attitude(data)
    yaw_lines = [ln for ln in fig.axes[2].get_lines() if not ln.get_label().startswith("_")]
    assert [ln.get_label() for ln in yaw_lines] == ["estimate", "truth"]
    assert np.allclose(yaw_lines[0].get_ydata(), np.degrees(yaw), atol=1e-7)


def test_a_log_without_a_body_frame_gets_no_body_figure(tmp_path):
    rows = np.empty(3, dtype=[(c, "f8") for c in ("t_s", "b1_x_m", "b1_y_m", "b1_z_m")])
    rows["t_s"], rows["b1_x_m"], rows["b1_y_m"], rows["b1_z_m"] = [0, 1, 2], 0.1, 0.2, 0.3
    write_log(tmp_path / "log", {"nodes": rows}, shipped("scene", "prism-gyro"))
    written = [p.name for p in plot_log(tmp_path / "log", tmp_path / "plots")]
    assert "fig7-nodes.png" in written and "body-attitude.png" not in written
