"""The estimator replayed over runs recorded on the real-time simulated rig, batch by batch.

``python -m studies estimator_replay [--batch T]``: each batch's runs (``data/``,
recorded with ``gyrotens sil --realtime`` through the run loop, every other job on the machine
stopped) replayed with the keys a run on the simulated rig takes today (``for_rig``), each
started off the truth by its seed's draw; printed per batch: the run-averaged NEES and the NIS
of every source against the 95 % bounds of their average, the share of time steps inside, the
wheel block and the tilt error. The recordings fix the loop's timing, so the replaying machine
enters only through its round-off.

The batch: T (10 runs), recorded with the emulators the shipped keys describe (an IMU sample
sent when its bits have crossed the wire). Recordings of earlier emulators do not replay with
today's keys, whose figures derive from the emulators; their batches left the repository
(reports/estimator-history.md). Per run the archive holds the log's ``meta.json`` and the
streams a replay reads; the live ``estimate`` cut to its first and last row, the span a replay
covers.
"""

import argparse
import json
import tarfile
import tempfile
from pathlib import Path

from gyrohost.config import load_rig_config
from gyrohost.estimator.config import for_rig
from gyrohost.resources import shipped
from gyrohost.sil.montecarlo import START_SEED_OFFSET, summarise
from gyrohost.sil.scoring import score_log

DATA = Path(__file__).parent / "data"
BATCHES = {"T": ("realtime-runs-T.tar.xz", 10)}


def unpacked(batch: str, root: Path) -> list[Path]:
    """A batch's run folders under ``root``, each pointed at the shipped scene (``meta.json``
    holds the recording machine's path)."""
    name, count = BATCHES[batch]
    with tarfile.open(DATA / name) as tar:
        tar.extractall(root, filter="data")
    scene = str(shipped("scene", "dbar-gyro"))
    folders = []
    for k in range(1, count + 1):
        folder = root / f"run{k:02d}"
        meta = json.loads((folder / "meta.json").read_text())
        meta["scene"] = scene
        (folder / "meta.json").write_text(json.dumps(meta))
        folders.append(folder)
    return folders


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m studies.estimator_replay")
    parser.add_argument("--batch", nargs="+", choices=sorted(BATCHES), default=sorted(BATCHES))
    args = parser.parse_args(argv)
    config = for_rig(load_rig_config(shipped("config", "sim-rig")))
    for batch in args.batch:
        with tempfile.TemporaryDirectory() as tmp:
            runs = unpacked(batch, Path(tmp))
            results = [
                score_log(folder, config=config, start_seed=k + START_SEED_OFFSET)
                for k, folder in enumerate(runs, start=1)
            ]
        print(f"--- batch {batch}: {len(runs)} runs")
        summarise(results, f"[{batch}] ")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
