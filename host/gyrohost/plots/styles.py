"""Line styles of figures whose lines can lie on top of each other (nodes at one coordinate,
wheels that spin alike, bars with equal errors): each line its own colour, dash pattern and
marker, the markers at staggered samples so that coinciding lines still show both."""

import matplotlib.pyplot as plt

DASHES = ("-", (0, (6, 2)), (0, (1.5, 1.5)), (0, (6, 2, 1.5, 2)), (0, (3, 3)), (0, (8, 3, 2, 3)))
MARKERS = ("o", "s", "^", "D", "v", "P")
MARKS_PER_LINE = 12


def colors() -> list:
    return plt.rcParams["axes.prop_cycle"].by_key()["color"]


def style(i: int, n_points: int, truth: bool = False) -> dict:
    """Keyword arguments of ``plot`` for the ``i``-th of several lines of ``n_points`` points
    each: colour, dash pattern and marker its own, about :data:`MARKS_PER_LINE` markers
    starting a quarter of their spacing later than line ``i - 1``'s; a truth line thin and
    dashed with the hollow marker of its index."""
    every = max(n_points // MARKS_PER_LINE, 1)
    kw = {
        "color": colors()[i % len(colors())],
        "marker": MARKERS[i % len(MARKERS)],
        "markevery": (min(i * every // 4, n_points - 1) if n_points else 0, every),
        "ms": 3.5,
    }
    if truth:
        return {**kw, "ls": (0, (4, 2)), "lw": 0.8, "mfc": "none"}
    return {**kw, "ls": DASHES[i % len(DASHES)], "lw": 1.1}
