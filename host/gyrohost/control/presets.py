"""Shipped schedules (presets) for the D-bar; other scenes take schedule files."""

import numpy as np

from .attitude import PLANE_NODES, has_plane
from .errors import ScheduleError
from .reduced import DBarReduced
from .schedule import Schedule


def paper(model, fraction=1.0 / 3.0, duration_s=3.0, sample_dt_s=0.1) -> Schedule:
    """The paper's open-loop maneuver (Section VI): the n1-n3 rest length goes linearly to
    ``fraction`` of its initial length in ``duration_s``; the n2-n4 rest length follows the
    rhombus geometry ``sqrt(4 l^2 - d13^2)``, sampled every ``sample_dt_s`` (as
    the shipped scene ``dbar-gyro`` does).

    Note: at 1/3 in 3 s the n1-n3 string moves at 0.096 m/s, above the default servo limit
    (0.05 m/s); :meth:`Schedule.problems` reports it.
    """
    dbar = DBarReduced(model)
    n = int(np.ceil(duration_s / sample_dt_s - 1e-9))
    t = np.linspace(0.0, duration_s, n + 1)
    d = dbar.d_rest * (1.0 + (fraction - 1.0) * t / duration_s)
    names = tuple(model.scene.strings[i].name for i in (dbar.i13, dbar.i24))
    return Schedule(names, t, np.column_stack([d, dbar.follower_length(d)]), "paper")


PRESETS = {"paper": paper}


def preset(name: str, model) -> Schedule:
    """The preset ``name`` (see :data:`PRESETS`) for ``model``."""
    if name not in PRESETS:
        raise ScheduleError(f"unknown preset '{name}' (choose one of: {', '.join(PRESETS)})")
    if not has_plane(model):
        raise ScheduleError(
            f"preset '{name}' is for the D-bar (nodes {', '.join(PLANE_NODES)}); scene "
            f"{model.scene.name} has none: give a schedule file (docs/schedule.md)"
        )
    return PRESETS[name](model)
