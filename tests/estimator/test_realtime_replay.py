"""The estimator on runs recorded on the real-time simulated rig through the run loop
(``gyrotens sil --realtime``, recorded with every other job on the machine stopped), replayed
with the keys a run on the simulated rig takes today (``estimator.config.for_rig``): the
run-averaged NEES and the NIS of every source must lie inside the 95 % chi-square bounds of
their average. The recordings fix the real-time loop's timing, so the machine that runs the
test does not enter; two batches from two machines (batch F, eight runs, and batch L, ten runs
on a machine where the IMU's samples reach the host 0.7 ms sooner, docs/estimator.md) hold the
keys to what differs between machines. Batches M and N (ten runs each on batch L's machine and
on another) were recorded after the emulated wheels got their speed loop's error (``[sim.wheels]
speed_error_std_rad_s``, docs/rig.md), batch P after the emulated servos got their hold band (a
resting servo stops anywhere within a count of its goal, ``[sim.servos] hold_band_steps``; before,
exactly on it). Batches F and L have wheels that hold their speeds exactly, where the wheel block
sits far under its dof, so only M's, N's and P's wheel blocks are held to their bounds. The
share of time steps inside their per-step bounds (:data:`STEPS_INSIDE`, the resting lead-in
included) is held on M, N and P.

The data (``data/realtime-runs*.tar.xz``): per run the log's
``meta.json`` and the streams a replay reads (imu, wheels, servos, command, truth); the live
``estimate`` cut to its first and last row, the span a replay covers (the replay's figures are
the same to the bit as with the whole stream). ``meta.json``'s scene path is the recording
machine's, so each is pointed at the shipped scene here."""

import json
import tarfile
from pathlib import Path

import pytest

from gyrohost.config import load_rig_config
from gyrohost.estimator.config import for_rig
from gyrohost.estimator.consistency import average_bounds
from gyrohost.resources import shipped
from gyrohost.sil.montecarlo import START_SEED_OFFSET, summarise
from gyrohost.sil.scoring import score_log

DATA = Path(__file__).parent / "data"
BATCHES = {
    "F": ("realtime-runs.tar.xz", 8),
    "L": ("realtime-runs-L.tar.xz", 10),
    "M": ("realtime-runs-M.tar.xz", 10),
    "N": ("realtime-runs-N.tar.xz", 10),
    "P": ("realtime-runs-P.tar.xz", 10),
}
# the target of the share of time steps whose run-averaged NEES is inside its bounds (measured
# 92.8, 87.5 and 94.5 % on M, N and P, docs/estimator.md)
STEPS_INSIDE = 0.85
SOURCES = ("imu_rate", "imu_accel", "imu_angle", "wheels", "servos")


@pytest.fixture(scope="module", params=sorted(BATCHES))
def runs(request, tmp_path_factory):
    """A batch's run folders, each pointed at the shipped scene."""
    name, count = BATCHES[request.param]
    root = tmp_path_factory.mktemp(f"realtime-{request.param}")
    with tarfile.open(DATA / name) as tar:
        tar.extractall(root, filter="data")
    scene = str(shipped("scene", "dbar-gyro"))
    folders = []
    for k in range(1, count + 1):
        folder = root / f"run{k:02d}"
        meta = json.loads((folder / "meta.json").read_text())
        assert meta["rig_config"]["scene"] == "dbar-gyro"
        meta["scene"] = scene
        (folder / "meta.json").write_text(json.dumps(meta))
        folders.append(folder)
    return folders


@pytest.fixture(scope="module")
def config():
    return for_rig(load_rig_config(shipped("config", "sim-rig")))


@pytest.fixture(scope="module")
def figures(runs, config):
    """The table ``gyrotens sil --realtime --score-only`` prints, over a batch's replays, each
    started off the truth by its seed's draw."""
    results = [
        score_log(folder, config=config, start_seed=k + START_SEED_OFFSET)
        for k, folder in enumerate(runs, start=1)
    ]
    return summarise(results, "[replay] ")


def inside(figure) -> bool:
    return figure["lo"] <= figure["mean"] <= figure["hi"]


def test_nees_inside_its_bounds(figures):
    nees = figures["nees"]
    assert nees["dof"] == 14  # observed: the nodes on the manifold, wheels, rest lengths
    assert inside(nees), nees


@pytest.mark.parametrize("runs", ["M", "N", "P"], indirect=True)
def test_wheel_block_inside_its_bounds_where_the_wheels_err(runs, figures):
    """The wheel speeds' marginal NEES, run-averaged, inside the 95 % bounds of its average on
    the batches whose wheels err as the filter's lag model says (module docstring)."""
    wheels = figures["blocks"]["wheels"]
    lo, hi = average_bounds(wheels["dof"], len(runs))
    assert wheels["dof"] == 4 and lo <= wheels["mean"] <= hi, wheels


@pytest.mark.parametrize("runs", ["M", "N", "P"], indirect=True)
def test_nees_inside_its_bounds_at_most_time_steps(runs, figures):
    """With the rest-length jitter of the servos' goal steps (``sawtooth_psd``) the run-averaged
    NEES stays inside its per-step bounds through the manoeuvre (with the truth's step alone,
    4e-10, 75.1 % of M's steps were, the positions high wherever the strings move fast), and
    with the resting servos' hold and the goal steps' spread kept whatever the filter's steps
    (``rest_hold_std_m``, ``servo_step_std_ratio``) through the rests before and after it as
    well (with a walk of 1e-7 instead, 90.3, 83.2 and 83.5 % of M's, N's and P's steps were)."""
    share = figures["nees"]["inside"]
    assert share >= STEPS_INSIDE, f"NEES inside its bounds at {100 * share:.1f} % of steps"


@pytest.mark.parametrize("source", SOURCES)
def test_nis_inside_its_bounds(figures, source):
    assert inside(figures[f"nis_{source}"]), figures[f"nis_{source}"]


def test_the_tilt_is_followed_to_a_few_hundredths_of_a_degree(figures):
    assert figures["tilt_rms_deg"] < 0.06


def test_a_seeded_replay_starts_off_the_truth_by_its_draw(runs, config):
    """Unseeded, a replay starts at the simulated rig's exact start, and the structure's
    position, which no sensor sees, keeps that zero error all run; seeded, it starts off it
    by a draw from the initial covariance (2 mm per coordinate), the same for the same seed."""
    exact = score_log(runs[0], config=config)
    drawn = score_log(runs[0], config=config, start_seed=11)
    again = score_log(runs[0], config=config, start_seed=11)
    assert exact.position_m.max() < 1e-3  # measured 0.47 mm
    assert min(drawn.position_m[0], drawn.position_m[-1]) > 1.2e-3  # measured 1.6 and 2.9 mm
    assert (drawn.nees == again.nees).all() and (drawn.position_m == again.position_m).all()
