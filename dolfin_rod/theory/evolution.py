"""Evolution of the natural configuration: the local and the uniform variants.

Local   (eq. unatevol/vnatevol):         M_d du_d/dt = -dpsi/du_d          pointwise,
Uniform (eq. unatevolunif/vnatevolunif): M_d du_d/dt = -int_0^L dpsi/du_d ds.

Both are the same weak form int (M_d/|I| du_d/dt + dpsi/du_d) . zeta ds: with zeta in a
discontinuous space (|I| = 1, the local law holds cell by cell) or in a real space
(zeta constant, |I| = L, the integral law), so the two variants share one residual.
Units: the uniform law's M_d carries one more length factor than the local one
(docs/rod.md); for L != 1 the same numbers relax L times faster in the uniform variant.
"""

from __future__ import annotations

import ufl

from ..fem import compat

VARIANTS = ("local", "uniform")


def check_variant(variant: str) -> str:
    if variant not in VARIANTS:
        raise ValueError(f"unknown evolution variant '{variant}' (known: {', '.join(VARIANTS)})")
    return variant


def evolution_residual(M_d, natural_rate, dpsi_dnatural, test, variant: str, length: float,
                       dx: ufl.Measure):
    """Weak form of the evolution law of one natural strain (see module docstring)."""
    scale = 1.0 / length if check_variant(variant) == "uniform" else 1.0
    if ufl.shape(natural_rate) == ():
        flow = scale * M_d * natural_rate
        return (flow + dpsi_dnatural) * test * dx
    flow = scale * ufl.dot(M_d, natural_rate)
    return ufl.inner(flow + dpsi_dnatural, test) * dx


def real_space(mesh, shape: tuple[int, ...] = ()):
    """The space of the uniform variant's global natural strains: a real space (scifem's
    with DOLFINx 0.9, which needs a mesh on MPI.COMM_WORLD; basix's from 0.10)."""
    return compat.real_space(mesh, shape)
