"""Dissipation rates (eq. disspw with the constitutive laws of Section 4.2).

With m = dpsi/du + M du/dt and n = dpsi/dv + N dv/dt, eq. disspw reduces to

    xi = du/dt.M du/dt + dv/dt.N dv/dt - dpsi/du_d . du_d/dt - dpsi/dv_d . dv_d/dt,

for either evolution variant.  Locally the last terms equal du_d/dt.M_d du_d/dt >= 0;
in the uniform variant they may be negative at a point (Section 4.3, errata item 4),
while their integral is |M_d^{-1/2} int dpsi/du_d|^2 >= 0.
"""

from __future__ import annotations

import ufl


def _rate_form(rate, M):
    return M * rate * rate if ufl.shape(rate) == () else ufl.dot(rate, ufl.dot(M, rate))


def dissipation_rate(pairs_viscous, pairs_natural):
    """xi from [(strain rate, viscosity)] and [(natural rate, dpsi/d natural strain)]."""
    xi = sum(_rate_form(rate, M) for rate, M in pairs_viscous)
    xi += sum(-ufl.inner(dpsi, rate) for rate, dpsi in pairs_natural)
    return xi
