"""The speed/accuracy trade: every integrator x step or tolerance x model variant.

Each case is integrated once with a tight reference (DOP853, rtol 1e-13) and then with every
setting of the grid; a run gives wall time per simulated second, node error against the
reference, bar-length and joint errors, energy and momentum drift.
"""

from dataclasses import dataclass

from gyrohost.resources import shipped_dir
from gyrotensegrity import Model, load_scene, scene_from_dict
from gyrotensegrity.compat import tomllib
from gyrotensegrity.generators import prism_chain

from .runner import Variant, errors, integrate

SCENES = shipped_dir("scene")
REFERENCE = ("dop853", 1e-13)
ACCURACY_CLASSES_M = (1e-3, 1e-6, 1e-9)

GRID_FULL = {
    "rk4": (2e-3, 1e-3, 5e-4, 2e-4, 1e-4, 5e-5),
    "rk4-projected": (1e-3, 2e-4),
    "dop853": (1e-5, 1e-7, 1e-9, 1e-10, 1e-11),
    "rk45": (1e-5, 1e-7, 1e-9),
    "radau": (1e-5, 1e-7),
    "bdf": (1e-5, 1e-7),
}
GRID_SMALL = {"rk4": (1e-3, 2e-4), "dop853": (1e-7, 1e-10)}  # secondary variants
GRID_QUICK = {"rk4": (1e-3,), "rk4-projected": (1e-3,), "dop853": (1e-8,), "radau": (1e-5,)}


@dataclass
class Case:
    """One scenario: its variants (the first is the main one) and run length."""

    name: str
    variants: list
    duration_s: float
    sample_dt_s: float = 0.01


def dbar_model(damping=None) -> Model:
    """The paper's D-bar maneuver (the shipped dbar-gyro scene), optionally with string damping
    replaced (MuJoCo's tendon damping cannot switch off while a string is slack)."""
    if damping is None:
        return Model(load_scene(SCENES / "dbar-gyro.toml"))
    with open(SCENES / "dbar-gyro.toml", "rb") as fh:
        data = tomllib.load(fh)
    for s in data["strings"]:
        s["damping"] = damping
    return Model(scene_from_dict(data, source="dbar-gyro.toml (no string damping)"))


def _spinless(kw) -> tuple:
    """The gyroscopic term left out for the no-spin variant (its wheels never turn)."""
    return () if kw["spin_rad_s"] else ("gyroscopic",)


def cases(quick: bool) -> list:
    dbar = dbar_model()
    nospin = Model(load_scene(SCENES / "dbar-nospin.toml"), omit=("gyroscopic",))
    prisms = 2 if quick else 4
    chain = [
        ("class-1 chain, wheels spinning", dict(spin_rad_s=50.0)),
        ("no spin (gyroscopic off)", dict(spin_rad_s=0.0)),
        ("string mass 10 g", dict(spin_rad_s=50.0, string_mass_kg=0.01)),
        ("joined (class-2 chain, reduced)", dict(spin_rad_s=50.0, joined=True)),
    ]
    chain_variants = [
        Variant(name, Model(prism_chain(prisms, duration_s=1.0, **kw), omit=_spinless(kw)))
        for name, kw in chain
    ]
    chain_variants.append(Variant("joined, full coordinates", chain_variants[-1].model, "full"))
    return [
        Case(
            "D-bar maneuver (dbar-gyro)",
            [
                Variant("reduced order (class-2)", dbar),
                Variant("full coordinates + multipliers", dbar, "full"),
                Variant("no spin (gyroscopic off)", nospin),
            ],
            duration_s=0.5 if quick else 3.0,
        ),
        Case(f"prism chain ({3 * prisms} bars)", chain_variants, duration_s=0.3 if quick else 1.0),
    ]


def run_case(case: Case, quick: bool, log=print) -> list:
    """All runs of a case; returns rows (dicts) with settings, cost and errors."""
    rows = []
    budget = 5.0 if quick else 30.0
    for k, variant in enumerate(case.variants):
        ref = integrate(variant, *REFERENCE, case.duration_s, case.sample_dt_s)
        if ref.failure:
            log(f"  {variant.name}: reference failed: {ref.failure}")
            continue
        grid = GRID_QUICK if quick else (GRID_FULL if k == 0 else GRID_SMALL)
        for method, settings in grid.items():
            if method == "rk4-projected" and variant.coordinates == "full":
                continue  # the projection works on the reduced state
            for setting in settings:
                run = integrate(variant, method, setting, case.duration_s, case.sample_dt_s, budget)
                row = {
                    "case": case.name,
                    "variant": variant.name,
                    "main": k == 0,
                    "method": method,
                    "setting": setting,
                    "setting_kind": "dt_s" if method.startswith("rk4") else "rtol",
                    "wall_s": run.wall_s,
                    "wall_per_sim_s": run.wall_s / case.duration_s,
                    "nfev": run.nfev,
                    "failure": run.failure,
                }
                if not run.failure:
                    row |= errors(variant, run, ref)
                rows.append(row)
                log(
                    f"  {variant.name:34s} {method:13s} {setting:8.0e} "
                    f"{row['wall_per_sim_s']:8.3f} s/s  "
                    + (f"node {row['node_error_m']:.1e} m" if not run.failure else run.failure)
                )
    return rows


def recommend(rows: list) -> list:
    """Fastest setting of the main variant of each case reaching each accuracy class."""
    out = []
    for case in dict.fromkeys(r["case"] for r in rows):
        main = [r for r in rows if r["case"] == case and r["main"] and not r["failure"]]
        for cls in ACCURACY_CLASSES_M:
            ok = [r for r in main if r["node_error_m"] <= cls]
            best = min(ok, key=lambda r: r["wall_per_sim_s"]) if ok else None
            out.append({"case": case, "class_m": cls, "row": best})
    return out
