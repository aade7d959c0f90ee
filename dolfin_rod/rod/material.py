"""Material data of the 3-D rod and their checks (Sections 2.2, 4.1, 4.2).

Tensors are 3 diagonal entries, a 3x3 matrix, or a callable of s returning either
(usable on floats and on UFL expressions); scalars are floats or callables of s.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import dolfinx.fem as fem
import numpy as np
import ufl

from ..fem.fe_model import scalar_coefficient
from ..checks import rod_length, sample_points

Tensor = Sequence | np.ndarray | Callable | None
TENSORS = ("A", "B", "A_d", "B_d", "M", "N", "M_d", "N_d", "rotational_drag",
           "spatial_rotational_drag")
DAMPING = ("rotational_drag", "spatial_rotational_drag")
SCALARS = ("rho_A", "I11", "I22", "drag")


@dataclass
class RodParameters:
    """Material data (tensors: 3 diagonal entries, a 3x3 SPD matrix, or a callable of s
    returning either, usable on floats and on UFL expressions)."""

    length: float = 1.0
    A: Tensor = (1.0, 1.0, 1.0)      # bending/torsion stiffness (EI_1, EI_2, GJ)
    B: Tensor = (1.0, 1.0, 1.0)      # shear/axial stiffness (GA_1, GA_2, EA)
    A_d: Tensor = (1.0, 1.0, 1.0)    # natural-curvature stiffness (eq. quadenergy)
    B_d: Tensor = (1.0, 1.0, 1.0)    # natural-stretch stiffness
    M: Tensor = None                 # Kelvin-Voigt viscosities (eq. xichoice); None: 0
    N: Tensor = None
    M_d: Tensor = (1.0, 1.0, 1.0)    # natural-configuration viscosities; uniform variant:
    N_d: Tensor = (1.0, 1.0, 1.0)    #   per unit length too (evolution.py, docs/rod.md)
    rho_A: float | Callable = 0.0    # mass per length; 0: quasi-static
    I11: float | Callable = 0.0      # section mass moments (rho J, Section 2.2)
    I22: float | Callable = 0.0
    drag: float | Callable = 0.0     # linear drag f = -c dr/dt
    rotational_drag: Tensor = None   # couple -C W per length (material W, C); None: 0
    spatial_rotational_drag: Tensor = None   # couple -C w per length (spatial w = R W, C)
    energy: Callable | None = None   # psi(u_d, v_d, u, v); None: quadratic_energy
    reference_curvature: Sequence[float] = (0.0, 0.0, 0.0)  # stress-free strains at t = 0
    reference_stretch: Sequence[float] = (0.0, 0.0, 1.0)
    reference_shape: object = None   # or the stress-free shape as a curve of rod/start.py
                                     # (Arc, Helix, Polyline: a kinked or bent frame)


def is_zero(value) -> bool:
    """None or all zeros (a callable is never zero)."""
    if value is None:
        return True
    if callable(value):
        return False
    return not np.any(np.asarray(value, dtype=float))


def _sample(name, value, length):
    """(s, values): at the sample points for a function of s, once for a constant."""
    s = sample_points(length) if callable(value) else np.zeros(1)
    try:
        vals = [np.asarray(value(si) if callable(value) else value, dtype=float) for si in s]
    except Exception as err:  # noqa: BLE001 - reported with the parameter's name
        raise ValueError(f"{name}: cannot evaluate ({err})") from err
    return s, vals


def check_tensor(name: str, value, length: float, semidefinite: bool = False) -> None:
    """ValueError unless value is a symmetric positive (semi)definite tensor along s."""
    s, vals = _sample(name, value, length)
    for si, a in zip(s, vals):
        if a.shape == (3,):
            a = np.diag(a)
        if a.shape != (3, 3):
            raise ValueError(f"{name} must have 3 diagonal entries or be 3x3, got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name} must be finite (s = {si:g})")
        if not np.allclose(a, a.T, rtol=1e-12, atol=1e-14 * np.abs(a).max()):
            raise ValueError(f"{name} must be symmetric (s = {si:g})")
        eig = np.linalg.eigvalsh(a)
        if (eig.min() < 0) if semidefinite else (eig.min() <= 0):
            rule = "positive semidefinite" if semidefinite else "positive definite (SPD)"
            raise ValueError(f"{name} must be {rule}; eigenvalue {eig.min():g} at s = {si:g}")


def check_scalar(name: str, value, length: float) -> None:
    """ValueError unless value is a finite scalar >= 0 along s."""
    _, vals = _sample(name, value, length)
    for a in vals:
        if a.shape != () or not np.isfinite(a) or a < 0:
            raise ValueError(f"{name} must be a finite scalar >= 0, got {a}")


def check_parameters(params: RodParameters, evolving: bool, viscous: bool,
                     variant: str) -> None:
    """The rules of every parameter of the chosen model (see RodModel)."""
    L = rod_length(params.length)
    for name in ("A", "B") + (("A_d", "B_d", "M_d", "N_d") if evolving else ()):
        check_tensor(name, getattr(params, name), L)
    if evolving and variant == "uniform":
        for name in ("M_d", "N_d"):
            if callable(getattr(params, name)):
                raise ValueError(f"{name} must be constant for the uniform variant "
                                 "(one tensor for the whole rod, eq. dotmfupequnif)")
    for name in ("M", "N"):
        value = getattr(params, name)
        if value is not None:
            if not viscous and not is_zero(value):
                raise ValueError(f"{name} must be None for the hyperelastic model")
            check_tensor(name, value, L, semidefinite=True)
    for name in DAMPING:
        if getattr(params, name) is not None:
            check_tensor(name, getattr(params, name), L, semidefinite=True)
    for name in SCALARS:
        check_scalar(name, getattr(params, name), L)
    if is_zero(params.rho_A):
        for name in ("I11", "I22"):
            if not is_zero(getattr(params, name)):
                raise ValueError(f"{name} > 0 needs rho_A > 0: with rho_A = 0 the rod is "
                                 "quasi-static and its rotary inertia would be dropped")
    for name in ("reference_curvature", "reference_stretch"):
        if np.shape(getattr(params, name)) != (3,):
            raise ValueError(f"{name} must be a 3-vector")
    if params.reference_stretch[2] <= 0:
        raise ValueError("reference_stretch[2] (v_3) must be > 0 (eq. v3pos)")


def ufl_tensor(value, mesh, s):
    """A tensor parameter as UFL: a constant 3x3 matrix, or value(s) for a callable."""
    if callable(value):
        a = value(s)
        if np.shape(np.asarray(value(0.0), dtype=float)) == (3,):
            return ufl.diag(ufl.as_vector(list(a)))
        return ufl.as_matrix([list(row) for row in a])
    a = np.asarray(value, dtype=float)
    return fem.Constant(mesh, np.diag(a) if a.shape == (3,) else a)


def coefficients(params: list[RodParameters], pieces) -> dict:
    """Every nonzero tensor and every scalar as UFL, by parameter name, and the section's
    rotary inertia J = diag(I22, I11, I11 + I22) (rho J of Section 2.2).  Several rods
    (``params`` per rod, ``pieces``: layout.Pieces): each rod's value on its cells, a
    DG0 field where every rod gives a constant, else sum_k chi_k value_k(s - a_k)."""
    if len(params) == 1:
        mesh, s = pieces.mesh, pieces.s
        c = {n: ufl_tensor(getattr(params[0], n), mesh, s) for n in TENSORS
             if not is_zero(getattr(params[0], n))}
        for n in SCALARS:
            c[n] = scalar_coefficient(getattr(params[0], n), mesh, s)
    else:
        c = {n: _piecewise(n, [getattr(p, n) for p in params], pieces, (3, 3))
             for n in TENSORS if not all(is_zero(getattr(p, n)) for p in params)}
        c.update({n: _piecewise(n, [getattr(p, n) for p in params], pieces, ())
                  for n in SCALARS})
    c["J"] = ufl.diag(ufl.as_vector((c["I22"], c["I11"], c["I11"] + c["I22"])))
    return c


def _piecewise(name: str, values: list, pieces, shape: tuple[int, ...]):
    """A parameter of several rods (None or zero: 0 on that rod)."""
    def constant(v):
        if is_zero(v):
            return np.zeros(shape)
        a = np.asarray(v, dtype=float)
        return np.diag(a) if shape == (3, 3) and a.shape == (3,) else a

    if not any(callable(v) for v in values):
        return pieces.cellwise([constant(v) for v in values], shape, name)
    total = 0
    for k, v in enumerate(values):
        if not is_zero(v):
            s_k = pieces.local_s(k)
            part = ufl_tensor(v, pieces.mesh, s_k) if shape else \
                scalar_coefficient(v, pieces.mesh, s_k)
            total = total + pieces.indicator(k) * part
    return total
