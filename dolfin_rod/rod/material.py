"""Material data of the 3-D rod and their checks (Sections 2.2, 4.1, 4.2).

Tensors are 3 diagonal entries, a 3x3 matrix, or a callable of s returning either
(usable on floats and on UFL expressions); scalars are floats or callables of s.  The
drag is either: a scalar c (isotropic, f = -c dr/dt) or a tensor C in the directors'
frame (anisotropic, f = -R C R^T dr/dt: resistive-force and slender-body theory,
sections.slender_body_drag).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import dolfinx.fem as fem
import numpy as np
import ufl

from ..fem.fe_model import scalar_coefficient
from ..checks import deprecated_names, old_keywords, rod_length, sample_points

Tensor = Sequence | np.ndarray | Callable | None
TENSORS = ("A", "B", "A_d", "B_d", "M", "N", "M_d", "N_d", "rotational_drag",
           "spatial_rotational_drag")
DRAG_TENSOR = "drag_tensor"          # the symbol of an anisotropic drag in the forms
DAMPING = ("rotational_drag", "spatial_rotational_drag")
SCALARS = ("rho_A", "I11", "I22", "drag")    # the scalar coefficients' symbols in the forms
SCALAR_FIELDS = ("density", "section_inertia", "drag")   # RodParameters' fields giving them
# RodParameters' keywords before they took the scene's names (deprecated, docs/rod.md)
RENAMED = {"rho_A": "density", "I11": "section_inertia=(I11, I22)",
           "I22": "section_inertia=(I11, I22)"}


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
    density: float | Callable = 0.0  # mass per length rho A (as the scene's material.density
                                     # without a [section]); 0: quasi-static
    section_inertia: float | Callable | Sequence = 0.0   # section mass moments rho I_11 =
                                     # rho I_22 (one value) or (rho I_11, rho I_22): rho J
                                     # of Section 2.2; stored as the pair
    drag: float | Callable | Tensor = 0.0   # linear drag: a scalar c, f = -c dr/dt, or a
                                     # tensor C in the directors' frame, f = -R C R^T dr/dt
                                     # (e.g. (c_n, c_n, c_t): sections.
                                     # slender_body_drag)
    rotational_drag: Tensor = None   # couple -C W per length (material W, C); None: 0
    spatial_rotational_drag: Tensor = None   # couple -C w per length (spatial w = R W, C)
    energy: Callable | None = None   # psi(u_d, v_d, u, v); None: quadratic_energy
    reference_curvature: Sequence[float] = (0.0, 0.0, 0.0)  # stress-free strains at t = 0
    reference_stretch: Sequence[float] = (0.0, 0.0, 1.0)
    reference_shape: object = None   # or the stress-free shape as a curve of rod/start.py
                                     # (Arc, Helix, Polyline: a kinked or bent frame)

    def __post_init__(self):
        self.section_inertia = inertia_pair(self.section_inertia)

    @property
    def rho_A(self):
        """Deprecated: ``density``."""
        deprecated_names("RodParameters", {"rho_A": None}, RENAMED)
        return self.density

    @property
    def I11(self):
        """Deprecated: ``section_inertia[0]``."""
        deprecated_names("RodParameters", {"I11": None}, RENAMED)
        return self.section_inertia[0]

    @property
    def I22(self):
        """Deprecated: ``section_inertia[1]``."""
        deprecated_names("RodParameters", {"I22": None}, RENAMED)
        return self.section_inertia[1]


def _new_names(old: dict) -> dict:
    """RodParameters' keywords of its deprecated ones (RENAMED)."""
    new = {"density": old["rho_A"]} if "rho_A" in old else {}
    if "I11" in old or "I22" in old:
        new["section_inertia"] = (old.get("I11", 0.0), old.get("I22", 0.0))
    return new


RodParameters.__init__ = old_keywords("RodParameters", RENAMED, _new_names)(
    RodParameters.__init__)


def inertia_pair(value) -> tuple:
    """section_inertia as (rho I_11, rho I_22): one value (a number or a function of s)
    for both, or a pair; ValueError otherwise."""
    if callable(value) or np.ndim(value) == 0:
        return (value, value)
    if len(value) != 2:
        raise ValueError(f"section_inertia must be one value (rho I_11 = rho I_22) or a "
                         f"pair (rho I_11, rho I_22), got {value!r}")
    return tuple(value)


def scalars(params: RodParameters) -> dict:
    """The scalar coefficients by their symbols in the forms (SCALARS): rho A (density),
    rho I_11, rho I_22 (section_inertia) and the drag c (0 for a drag tensor)."""
    drag = 0.0 if is_drag_tensor(params.drag) else params.drag
    return dict(zip(SCALARS, (params.density, *params.section_inertia, drag)))


def tensors(params: RodParameters) -> dict:
    """The tensor parameters by their symbols in the forms: TENSORS and DRAG_TENSOR
    (the drag if it is a tensor, else None)."""
    drag = params.drag if is_drag_tensor(params.drag) else None
    return {**{n: getattr(params, n) for n in TENSORS}, DRAG_TENSOR: drag}


def is_drag_tensor(value) -> bool:
    """Whether a drag is a tensor C (3 entries, 3x3, or a callable of s returning either)
    rather than a scalar c."""
    if callable(value):
        try:
            return np.ndim(value(0.0)) > 0
        except Exception:  # noqa: BLE001 - reported by check_parameters with its name
            return False
    return value is not None and np.ndim(value) > 0


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


def largest_entry(value, length: float) -> float:
    """The largest magnitude of a parameter's entries over s in [0, length] (a callable:
    at the sample points); ValueError if it cannot be evaluated at floats."""
    return max(float(np.abs(a).max()) for a in _sample("value", value, length)[1])


def check_tensor(name: str, value, length: float, semidefinite: bool = False) -> None:
    """ValueError unless value is a symmetric positive (semi)definite tensor along s."""
    s, vals = _sample(name, value, length)
    for si, a in zip(s, vals):
        diagonal = a.shape == (3,)      # symmetric, its entries its eigenvalues
        if not diagonal and a.shape != (3, 3):
            raise ValueError(f"{name} must have 3 diagonal entries or be 3x3, got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name} must be finite (s = {si:g})")
        if not diagonal and not np.allclose(a, a.T, rtol=1e-12, atol=1e-14 * np.abs(a).max()):
            raise ValueError(f"{name} must be symmetric (s = {si:g})")
        eig = a if diagonal else np.linalg.eigvalsh(a)
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
    if is_drag_tensor(params.drag):
        check_tensor("drag", params.drag, L, semidefinite=True)
    for name, value in zip(("density", "section_inertia[0]", "section_inertia[1]", "drag"),
                           scalars(params).values()):
        check_scalar(name, value, L)
    if is_zero(params.density) and not all(map(is_zero, params.section_inertia)):
        raise ValueError("section_inertia > 0 needs density > 0: with density = 0 the rod "
                         "is quasi-static and its rotary inertia would be dropped")
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
        c = {n: ufl_tensor(value, mesh, s) for n, value in tensors(params[0]).items()
             if not is_zero(value)}
        for n, value in scalars(params[0]).items():
            c[n] = scalar_coefficient(value, mesh, s)
    else:
        values = [tensors(p) for p in params]
        c = {n: _piecewise(n, [v[n] for v in values], pieces, (3, 3))
             for n in values[0] if not all(is_zero(v[n]) for v in values)}
        c.update({n: _piecewise(n, [scalars(p)[n] for p in params], pieces, ())
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
