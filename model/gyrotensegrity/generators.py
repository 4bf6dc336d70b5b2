"""Scenes generated in code: chains of tensegrity prisms of any size (benchmarks, tests).

A chain stacks ``k`` three-bar prisms (twist 150 deg) along z. ``joined=False`` (class 1):
each prism has its own six nodes; the top triangle of prism ``j`` and the bottom triangle of
prism ``j + 1`` lie in one plane, rotated by 60 deg, and six strings join them into a hexagon.
``joined=True`` (class 2): prism ``j + 1`` stands on the top nodes of prism ``j`` (class-2
joints, one multiplier column per shared node). Every bar may carry a spinning wheel, every
vertical string may be split by a point mass (string mass, Eq. 30).
"""

import numpy as np

from .scene import Scene, scene_from_dict

TWIST_DEG = 150.0


def _ring(radius, angle_deg, z):
    a = np.radians(angle_deg)
    return [radius * np.cos(a), radius * np.sin(a), z]


def prism_chain(
    prisms: int,
    joined: bool = False,
    spin_rad_s: float = 50.0,
    string_mass_kg: float = 0.0,
    radius_m: float = 0.15,
    height_m: float = 0.3,
    bar_mass_kg: float = 0.1,
    wheel_mass_kg: float = 0.04,
    stiffness_n_m: float = 50.0,
    damping_n_s_m: float = 0.0,
    prestress: float = 0.95,
    duration_s: float = 1.0,
) -> Scene:
    """A chain of ``prisms`` three-bar prisms (3 ``prisms`` bars), free-floating.

    Parameters
    ----------
    prisms : int, >= 1
    joined : bool
        Class-2 joints between consecutive prisms (True) or class 1 with hexagon strings.
    spin_rad_s : float, rad/s
        Wheel spin, alternating in sign over the bars; 0 builds the wheels but no gyroscopic
        terms; ``None`` builds no wheels at all.
    string_mass_kg : float, kg
        > 0 splits every vertical string at its midpoint by a point mass of this size.
    radius_m, height_m : float, m
        Ring radius and prism height.
    prestress : float
        Rest length as a fraction of the initial string length (< 1: strings taut).

    Returns
    -------
    Scene
    """
    if prisms < 1:
        raise ValueError(f"prism_chain needs at least one prism, got {prisms}")
    nodes, bars, strings, masses = {}, [], [], {}
    prev_top, theta = None, 0.0  # theta: angle of bottom node 0 of the current prism, deg
    for j in range(prisms):
        if joined and prev_top is not None:
            bottom = prev_top
        else:
            bottom = [f"p{j}b{i}" for i in range(3)]
            for i, name in enumerate(bottom):
                nodes[name] = _ring(radius_m, theta + 120 * i, j * height_m)
        top = [f"p{j}t{i}" for i in range(3)]
        for i, name in enumerate(top):
            nodes[name] = _ring(radius_m, theta + TWIST_DEG + 120 * i, (j + 1) * height_m)
        for i in range(3):
            bar = {"name": f"p{j}bar{i}", "nodes": [bottom[i], top[i]], "mass": bar_mass_kg}
            if spin_rad_s is not None:
                spin = spin_rad_s * (-1) ** (3 * j + i)
                bar["wheel"] = {
                    "mass": wheel_mass_kg,
                    "radius": 0.025,
                    "thickness": 0.01,
                    "spin": spin,
                }
            bars.append(bar)
        pairs = [(top[i], top[(i + 1) % 3]) for i in range(3)]
        if bottom is not prev_top:
            pairs += [(bottom[i], bottom[(i + 1) % 3]) for i in range(3)]
        if prev_top is not None and not joined:  # hexagon between the two triangles
            pairs += [(bottom[i], prev_top[i]) for i in range(3)]
            pairs += [(bottom[i], prev_top[(i + 1) % 3]) for i in range(3)]
        for a, b in [(bottom[i], top[(i + 1) % 3]) for i in range(3)]:  # verticals
            if string_mass_kg > 0:
                mid = f"m_{a}_{b}"
                nodes[mid] = list(0.5 * (np.array(nodes[a]) + np.array(nodes[b])) + [0, 0, 0.01])
                masses[mid] = string_mass_kg
                pairs += [(a, mid), (mid, b)]
            else:
                pairs.append((a, b))
        for a, b in pairs:
            dist = float(np.linalg.norm(np.subtract(nodes[a], nodes[b])))
            strings.append(
                {
                    "nodes": [a, b],
                    "stiffness": stiffness_n_m,
                    "damping": damping_n_s_m,
                    "rest_length": prestress * dist,
                }
            )
        prev_top = top
        theta += TWIST_DEG if joined else TWIST_DEG + 60.0
    data = {
        "scene": {
            "name": f"prism-chain-{prisms}{'-joined' if joined else ''}",
            "duration": duration_s,
        },
        "nodes": nodes,
        "bars": bars,
        "strings": strings,
    }
    if masses:
        data["point_masses"] = masses
    return scene_from_dict(data, source=f"prism_chain({prisms})")
