"""Run files (.npz): self-contained records of a simulation (layout in docs/model.md)."""

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

RUN_KEYS = (
    "t",
    "N",
    "N_dot",
    "node_names",
    "omega_w",
    "theta_w",
    "C_b",
    "C_s",
    "m_t",
    "J_t",
    "J_a",
    "bar_length",
    "m_node",
    "string_stiffness",
    "string_damping",
    "rest_length",
    "gravity",
    "W",
    "bar_length_error",
    "joint_error",
    "energy",
    "angular_momentum",
    "scene",
    "meta",
)


@dataclass
class Run:
    """Arrays of a run (docs/model.md#run-files-npz); ``meta`` is a dict."""

    arrays: dict
    meta: dict = field(default_factory=dict)

    def __getitem__(self, key):
        return self.arrays[key]

    def save(self, path) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        data = dict(self.arrays)
        data["meta"] = np.array(json.dumps(self.meta))
        with open(path, "wb") as fh:
            np.savez_compressed(fh, **data)
        return path


def load_run(path) -> Run:
    """Read a run file written by :meth:`Run.save`."""
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files if k != "meta"}
        meta = json.loads(str(z["meta"])) if "meta" in z.files else {}
    return Run(arrays, meta)
