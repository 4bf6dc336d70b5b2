"""The truth's body attitude at the estimate's time, and the summary's record of both."""

from types import SimpleNamespace

import pytest
from scipy.spatial.transform import Rotation

from gyrohost.control.attitude import body_frame_of
from gyrohost.resources import shipped
from gyrohost.run.streams import TruthProbe, body_summary, body_values
from gyrotensegrity import Model, load_scene


class _Log:
    def stream(self, *args, **kwargs):
        return SimpleNamespace(write=lambda *row: None)


@pytest.fixture(scope="module")
def dbar():
    return Model(load_scene(shipped("scene", "dbar-gyro")))


def turned(model, yaw_rad):
    return Rotation.from_rotvec([0.0, 0.0, yaw_rad]).as_matrix() @ model.scene.positions


def test_the_truth_between_two_samples_is_the_turn_between_them(dbar):
    """Nodes turned about z, interpolated half way: every node lies on the bisector of its two
    positions, so the frame has turned by exactly the mean angle."""
    body = body_frame_of(dbar)
    samples = [SimpleNamespace(N=turned(dbar, a), state_rig_t_s=t, rig_t_s=t, truth_t_s=t,
                               t_ns=0, omega_w_rad_s=(), rest_length_m=())
               for t, a in ((0.0, 0.2), (0.01, 0.3))]  # fmt: skip
    rig = SimpleNamespace(node_names=dbar.scene.node_names, n_wheels=0, string_names=[],
                          t0_ns=0, truth=lambda: samples)  # fmt: skip
    probe = TruthProbe(rig, _Log(), None, 0, body)
    assert probe.body_at(0.0) is None  # before any sample
    probe.write()
    assert probe.body_at(0.005)[4:] == pytest.approx((0.0, 0.0, 0.25), abs=1e-12)
    assert probe.body_at(-1.0)[6] == pytest.approx(0.2, abs=1e-12)  # the nearest outside
    assert probe.body_at(1.0)[6] == pytest.approx(0.3, abs=1e-12)


def test_the_summary_gives_the_geodesic_angle_between_estimate_and_truth(dbar):
    body = body_frame_of(dbar)
    true_turn = Rotation.from_rotvec([0.02, -0.03, 0.1])
    estimate = body_values(body, turned(dbar, 0.1))
    truth = body_values(body, true_turn.as_matrix() @ dbar.scene.positions)
    record = body_summary(estimate, truth)
    assert record["rpy_rad"] == pytest.approx([0.0, 0.0, 0.1], abs=1e-12)
    apart = (true_turn * Rotation.from_rotvec([0.0, 0.0, 0.1]).inv()).magnitude()
    assert record["error_rad"] == pytest.approx(apart, abs=1e-9)  # the D-bar's F0 is the world's
    assert 0.03 < apart < 0.04
    assert body_summary(estimate) == {"quaternion": list(estimate[:4]), "rpy_rad": [*estimate[4:]]}
