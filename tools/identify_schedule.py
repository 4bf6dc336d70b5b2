"""Write the shipped identification schedule ``host/gyrohost/schedules/identify.toml``.

The D-bar's n1-n3 string is pulled by the moves of :data:`MOVES` (from the square, at a speed,
held, back to the square at the same speed, then a rest), the n2-n4 string follows the rhombus
``sqrt(4 l^2 - d13^2)``; all four wheels step in the scene's pattern at the start of the rests
named in :data:`WHEEL_STEPS`. Samples every 0.05 s plus every corner; a wheel step takes one
sample interval. Usage: ``python tools/identify_schedule.py`` (docs/schedule.md).
"""

from pathlib import Path

import numpy as np

L0 = 0.43105229381822  # the square's n1-n3 distance, m
ROD_M = 0.3048  # the D-bar's bar length, m
SPIN = 74.87462492  # the scene's wheel spin, rad/s
PATTERN = {"b12": 1, "b23": -1, "b34": -1, "b41": 1}
FIRST_REST_S = 2.0
MOVES = [  # (change of d13 from the square m, speed m/s, hold s, rest after s)
    (-0.03, 0.10, 0.5, 1.0),
    (-0.02, 0.14, 0.3, 0.7),
    (-0.02, 0.14, 0.3, 0.7),
    (-0.02, 0.14, 0.3, 0.7),
    (-0.06, 0.10, 0.5, 1.5),
    (+0.018, 0.10, 2.0, 2.0),
    (-0.08, 0.05, 0.5, 2.0),
    (-0.03, 0.02, 1.0, 1.0),
    (-0.04, 0.03, 0.0, 1.5),
    (+0.018, 0.02, 2.0, 3.0),
]
WHEEL_STEPS = {0: 1.15, 4: 0.85, 5: 1.0, 6: 1.15, 8: 1.0}
"""Move index -> wheel speed factor from the start of the rest after that move on."""
OUT = Path(__file__).resolve().parents[1] / "host/gyrohost/schedules/identify.toml"
HEADER = """\
# Identification run (docs/schedule.md, "identify"), written by tools/identify_schedule.py: the
# n1-n3 string pulled from the square (0.43105 m) and back, with holds and rests: -3 cm at
# 0.10 m/s, three -2 cm steps at 0.14 m/s, -6 cm at 0.10 m/s, +1.8 cm at 0.10 m/s (to 0.449 m,
# inside the 0.45 m limit), -8 cm at 0.05 m/s, -3 cm at 0.02 m/s, a -4 cm triangle at 0.03 m/s
# and +1.8 cm at 0.02 m/s; the fast pulls first, so that the first 15 s hold most of what
# identifies the strings. The n2-n4 string follows the rhombus sqrt(4 l^2 - d13^2)
# (l = 0.3048 m), sampled every 0.05 s. Wheel speed steps, all four wheels together (pattern
# +, -, -, +), each at the start of a rest over one 0.05 s sample (the board ramps it at
# ACCEL_RAD_S2, 100 rad/s^2): 715 rpm (74.87 rad/s) x 1.15 after the first pull, x 0.85 after
# the -6 cm pull, x 1 after the first +1.8 cm, x 1.15 after the -8 cm, x 1 after the triangle
# (63.6..86.1 rad/s: inside [run] max_wheel_speed_rad_s and SPEED_MAX). Inside the servo limits
# of the shipped D-bar configs (sim-rig, lab-rig): s13 0.12..0.45 m, s24 0.40..0.62 m, 0.15 m/s.
"""


def corners() -> tuple[list[float], list[float], list[float]]:
    """Times (s) and n1-n3 lengths (m) of the moves' corners; the rest starts (s) in order."""
    t, d, rests = [0.0, FIRST_REST_S], [L0, L0], []
    for change, speed, hold, rest in MOVES:
        ramp = abs(change) / speed
        if hold > 0.0:
            t += [t[-1] + ramp, t[-1] + ramp + hold]
            d += [L0 + change, L0 + change]
        else:
            t.append(t[-1] + ramp)
            d.append(L0 + change)
        t.append(t[-1] + ramp)
        d.append(L0)
        rests.append(t[-1])
        t.append(t[-1] + rest)
        d.append(L0)
    return t, d, rests


def schedule_text() -> str:
    t_c, d_c, rests = corners()
    t = np.union1d(np.round(np.arange(0.0, t_c[-1], 0.05), 9), np.round(t_c, 9))
    d13 = np.interp(t, t_c, d_c)
    d24 = np.sqrt(4.0 * ROD_M**2 - d13**2)
    factor = np.ones_like(t)
    for move, f in WHEEL_STEPS.items():
        k = int(np.searchsorted(t, rests[move] - 1e-9))
        factor[k + 1 :] = f

    def arr(x, digits):
        return "[" + ", ".join(f"{v:.{digits}g}" for v in x) + "]"

    lines = [HEADER.rstrip("\n"), "[schedule]", 'name = "identify"', f"t_s = {arr(t, 12)}", ""]
    lines += ["[rest_length_m]", f"s13 = {arr(d13, 12)}", f"s24 = {arr(d24, 12)}", ""]
    lines += ["[wheel_speed_rad_s]"]
    lines += [f"{n} = {arr(s * SPIN * factor, 10)}" for n, s in PATTERN.items()]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    OUT.write_text(schedule_text())
    print(f"wrote {OUT}")
