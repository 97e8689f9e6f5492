"""Argument checks of the physics functions: NaN, infinities and non-physical values are
refused with one clear ``ValueError`` naming the argument, its value and the allowed range."""

from __future__ import annotations

import numpy as np

from humv_usd.errors import summary


def require(name: str, value, lo: float = -np.inf, hi: float = np.inf, *, allow_inf: bool = False):
    """``value`` as a float array if every element is a number in [lo, hi], else ValueError.

    Parameters
    ----------
    name : str
        Argument name for the message.
    value : numeric
        Scalar or array.
    lo, hi : float
        Allowed closed range (in the argument's unit).
    allow_inf : bool
        Accept +-inf inside the range (e.g. an infinite time step meaning steady state).
    """
    a = np.asarray(value, dtype=float)
    bad = np.isnan(a) | (a < lo) | (a > hi)
    if not allow_inf:
        bad |= np.isinf(a)
    if bad.any():
        kind = "numbers" if allow_inf else "finite numbers"
        raise ValueError(f"{name} = {summary(a[bad])}: expected {kind} in [{lo:g}, {hi:g}]")
    return a
