"""Complex-step derivatives: exact to round-off, no subtractive cancellation.

``f(x + i h e_j) = f(x) + i h df/dx_j + O(h^2)`` for a function analytic in its argument, so with
``h = 1e-20`` the imaginary part divided by ``h`` is the derivative to machine precision and the
real part is ``f(x)``. The functions differentiated here are written complex-safe (see
:class:`gyrotensegrity.fast.FastDynamics`); tests check the results against central finite
differences.
"""

import numpy as np

STEP = 1e-20


def perturbed(x, columns):
    """A batch of copies of ``x`` (n,) with ``i STEP`` added to entry ``columns[k]`` of copy k.

    Returns
    -------
    ndarray, shape (len(columns), n), complex
    """
    X = np.tile(np.asarray(x, dtype=complex), (len(columns), 1))
    X[np.arange(len(columns)), columns] += 1j * STEP
    return X


def split(Y):
    """Value (real part of the first row) and Jacobian columns of a perturbed batch result.

    Parameters
    ----------
    Y : ndarray, shape (K, k), complex: the function at the K perturbed copies

    Returns
    -------
    value : ndarray, shape (k,)
    jacobian : ndarray, shape (k, K): column j = derivative along the j-th perturbation
    """
    return Y[0].real.copy(), Y.imag.T / STEP


def atan2(y, x):
    """``arctan2`` that carries a complex-step derivative in the imaginary parts."""
    if not (np.iscomplexobj(y) or np.iscomplexobj(x)):
        return np.arctan2(y, x)
    xr, yr = x.real, y.real
    return np.arctan2(yr, xr) + 1j * (xr * y.imag - yr * x.imag) / (xr * xr + yr * yr)
