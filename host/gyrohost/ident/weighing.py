"""What weighing the bars leaves unknown of the parameters that scale with their mass.

Scaling every mass, inertia, stiffness and damping by one factor leaves the D-bar's motion
nearly unchanged (docs/identification.md, "The absolute scale"), so a fit with the scene's
weighed masses finds J3 and the strings' stiffness and damping relative to those masses: a bar
and wheel weighed 0.5 % light give all three about 0.5 % low, whatever the data. A scale of
resolution ``R`` rounds each reading by an error uniform within ``R / 2`` (standard deviation
``R / sqrt(12)``); the bar and its wheel weighed apart, their moving mass ``m_bar + m_wheel`` is
known to ``sqrt(2) R / sqrt(12)``, which the fit's own sigma of each such parameter (relative,
a log factor) is added to in quadrature.
"""

from dataclasses import replace

import numpy as np

from gyrohost.ident.fit import BAR_GROUPS

SCALED = ("J3", "J3-each", "stiffness", "damping")
"""Groups whose fitted value scales with the weighed masses (unless a group of
:data:`.fit.BAR_GROUPS` is fitted: the fit's scale is then its own)."""


def mass_sigma(scene, resolution_kg: float) -> float:
    """Relative 1-sigma of the lightest bar's moving mass (bar and wheel) weighed to
    ``resolution_kg``."""
    moving = min(b.mass + (0.0 if b.wheel is None else b.wheel.mass) for b in scene.bars)
    readings = np.sqrt(2.0) * resolution_kg / np.sqrt(12.0)
    return float(readings / moving)


def with_weighing(result, resolution_kg: float):
    """``result`` (:class:`.fit.FitResult`) with the weighing's :func:`mass_sigma` in the
    sigmas of its :data:`SCALED` parameters, unless the masses were fitted."""
    groups = {p.group for p in result.params}
    if resolution_kg <= 0.0 or groups & set(BAR_GROUPS):
        return result
    rel = mass_sigma(result.scene, resolution_kg)
    scaled = np.array([p.group in SCALED for p in result.params])
    sigma = np.where(scaled, np.hypot(result.sigma, rel), result.sigma)
    return replace(result, sigma=sigma, weighing_sigma=rel)
