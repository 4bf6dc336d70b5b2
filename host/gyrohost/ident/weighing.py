"""What weighing the bars and wheels leaves unknown of the parameters that scale with them.

Scaling every mass, inertia, stiffness and damping by one factor leaves the D-bar's motion
nearly unchanged (docs/identification.md, "The absolute scale"), so a fit with the scene's
weighed masses finds J3 and the strings' stiffness and damping relative to those masses. How
the optimum moves with the bars' mass, ``s = d theta / d log m_bar``, is the fit's linear
response (:func:`bar_mass_sensitivity`); the common scale then fixes the wheels' share: a
parameter that scales moves by ``1 - s`` with ``log m_wheel``. A scale of resolution ``R``
rounds each reading by an error uniform within ``R / 2`` (standard deviation ``R / sqrt(12)``),
so a bar of mass ``m_bar`` and a wheel of ``m_wheel`` weighed apart add::

    sigma_weighing^2 = (s R / sqrt(12) / m_bar)^2 + ((1 - s) R / sqrt(12) / m_wheel)^2

to the fit's own sigma of each such parameter (relative: a log factor), in quadrature.
"""

from dataclasses import replace

import numpy as np

from gyrohost.ident.params import parameters

SCALED = ("J3", "J3-each", "stiffness", "damping")
"""Groups whose fitted value scales with the weighed masses."""


def bar_mass_sensitivity(problem, theta, J) -> np.ndarray:
    """``d theta / d log m_bar``, shape (p,), of the fit's optimum ``theta`` of ``problem``
    (:class:`.fit.Problem`) whose Jacobian there is ``J`` (n, p): least squares of
    ``J s = -dr / d log m_bar``, the residual's central difference over the bar-mass group's
    step."""
    bar_mass = parameters(problem.scene, problem.config, ["bar-mass"], problem.servo_lag_s)[0]
    moved = problem.with_params([*problem.params, bar_mass])
    h = bar_mass.step
    dr = (moved(np.r_[theta, h]) - moved(np.r_[theta, -h])) / (2.0 * h)
    return np.linalg.lstsq(J, -dr, rcond=None)[0]


def weighing_sigma(scene, sensitivity, resolution_kg: float) -> np.ndarray:
    """The weighing's relative 1-sigma (module docstring) of each parameter whose bar-mass
    sensitivity is ``sensitivity`` (p,), the scene's mean bar and wheel weighed once each to
    ``resolution_kg``."""
    reading = resolution_kg / np.sqrt(12.0)
    bar = reading / np.mean([b.mass for b in scene.bars])
    wheels = [b.wheel.mass for b in scene.bars if b.wheel is not None]
    wheel = reading / np.mean(wheels) if wheels else 0.0
    return np.hypot(sensitivity * bar, (1.0 - sensitivity) * wheel)


def with_weighing(result, resolution_kg: float):
    """``result`` (:class:`.fit.FitResult`) with the weighing's sigma in those of its
    :data:`SCALED` parameters; as it is where the fit did not take the masses as weighed (no
    ``mass_sensitivity``: a bar group fitted, or the filter's fit) or ``resolution_kg`` is 0."""
    s = result.mass_sensitivity
    if resolution_kg <= 0.0 or s is None:
        return result
    scaled = np.array([p.group in SCALED for p in result.params])
    added = np.where(scaled, weighing_sigma(result.scene, s, resolution_kg), 0.0)
    return replace(result, sigma=np.hypot(result.sigma, added), weighing_sigma=added)
