"""The contact barrier's numbers (issue 26; rod/contact.py's module docstring, docs/
contact.md): b(g) = delta^2 beta(g / delta), beta(xi) = -(xi - 1)^2 ln(xi) on
[XI_MIN, 1], 0 beyond 1, its second-order Taylor polynomial at XI_MIN below; b, b', b''
in numpy (segment pairs, thin obstacles, friction, the cosseratbench adapter), no
DOLFINx (the UFL form is contact.barrier)."""

from __future__ import annotations

import math

import numpy as np

XI_MIN = 1e-4             # g_min / delta: the barrier's exact range is [g_min, delta]


def beta(xi):
    """-(xi - 1)^2 ln(xi), the barrier b(g) = delta^2 beta(g / delta) on [XI_MIN, 1]."""
    return -(xi - 1.0) ** 2 * math.log(xi)


TAYLOR = (beta(XI_MIN),                                   # beta and its derivatives at
          -2 * (XI_MIN - 1) * math.log(XI_MIN) - (XI_MIN - 1) ** 2 / XI_MIN,   # XI_MIN
          -2 * math.log(XI_MIN) - 4 * (XI_MIN - 1) / XI_MIN + (XI_MIN - 1) ** 2 / XI_MIN**2)


def barrier_derivatives(g, delta: float):
    """(b, b', b'') of contact.barrier at the gaps g (numpy; segment pairs, pair_contact.py)."""
    xi = np.asarray(g, float) / delta
    xc = np.clip(xi, XI_MIN, 1.0)
    ln = np.log(xc)
    exact = (-(xc - 1) ** 2 * ln, -2 * (xc - 1) * ln - (xc - 1) ** 2 / xc,
             -2 * ln - 4 * (xc - 1) / xc + (xc - 1) ** 2 / xc**2)
    b0, b1, b2 = TAYLOR
    dxi = xi - XI_MIN
    taylor = (b0 + b1 * dxi + 0.5 * b2 * dxi**2, b1 + b2 * dxi, b2 + 0 * dxi)
    return tuple(delta ** (2 - k) * np.where(xi >= 1.0, 0.0, np.where(xi >= XI_MIN, e, t))
                 for k, (e, t) in enumerate(zip(exact, taylor)))
