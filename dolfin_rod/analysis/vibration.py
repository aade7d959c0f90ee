"""Natural frequencies and mode shapes of a dynamic rod about its current state.

Small motions y = phi e^{i omega t} about an equilibrium (pre-stressed, pre-twisted,
with evolved natural strains: they are frozen, they move on the viscous time scale)
solve K phi = omega^2 M phi: K the tangent stiffness at the state and the loads of time
t (analysis/stability.py: rates and accelerations zero; its symmetric part unless
follower loads or couples act), M the
derivative of the residual with respect to the accelerations (rho A for the positions,
the rotary inertia rho J for the rotations, eqs. linmom, angmom), both with Dirichlet
rows and columns removed (K: identity, M: zero, so those dofs give omega = infinity).
The lowest pairs by analysis/eigen.py (shift-and-invert below the spectrum: rigid
modes, omega = 0, are found too).  Damping and gyroscopic terms are left out (undamped
modes; a state at rest).  Follower loads and couples (dead ones too: a couple of
fixed spatial direction is not conservative on 3-D rotations) are not conservative: K
is not symmetric and the pencil is solved as it is (non-Hermitian: analysis/eigen.py's "general"); where two
frequencies meet, omega^2 turns into a complex pair, a growing mode (flutter; Beck's
column in tests/test_vibration.py).  The quaternion form: its rotations' inertia enters through
the kinematic equation W = 2 vec(conj(q) q_t)/|q|^2, so M's rotation block is rho J in
the material rotations 2 vec(conj(q) dq)/|q|^2 of quaternion directions dq; K and M are
bordered by the gauge multiplier (|q| = 1), whose rows have no mass (infinite
eigenvalues, out of the way), and dq along q has neither energy nor mass: the modes are
those of the rotation vectors (tests/test_vibration.py compares them).  Rod systems with
joints: K and M on the free dofs, P^T K P and P^T M P (fem/multipoint.py).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import dolfinx.fem as fem
import numpy as np
import ufl
from petsc4py import PETSc

from ..fem import form_cache
from ..fem.assembly import block_system, monolithic_layout
from ..fem.multipoint import ConstrainedSystem
from ..theory.rotations import material_derivative_vector
from .eigen import eigenpairs
from .stability import TangentStiffness, at_rest_map, non_conservative, symmetric_part

__all__ = ["VibrationModes", "vibration_modes"]


@dataclass
class VibrationModes:
    """``omega``: angular frequencies (rad per time unit), ascending; ``frequencies``:
    omega / 2 pi; ``eigenvalues``: omega^2 (negative: an unstable state, omega then
    reported as -sqrt|omega^2|; below 1e-10 |K|/|M|: 0, a rigid mode); with follower
    loads or couples (a non-symmetric K) ``imaginary``: the imaginary parts of omega^2, a complex
    pair omega^2 = a +- i b is flutter: omega = Re sqrt(a + i b) and ``growth_rates`` =
    |Im sqrt(a + i b)| (the motion e^{i omega t} grows as e^{growth t}; 0 otherwise);
    ``shapes``: per mode {"displacement", "rotation"} nodal values (largest displacement
    1; of a complex pair its real part); ``residuals``: the eigen-solve's."""

    t: float
    eigenvalues: np.ndarray
    omega: np.ndarray
    frequencies: np.ndarray
    shapes: list[dict[str, np.ndarray]]
    residuals: np.ndarray
    imaginary: np.ndarray
    growth_rates: np.ndarray

    @property
    def flutter(self) -> bool:
        """Whether a mode grows (a complex pair of omega^2: non-conservative loads)."""
        return bool(np.any(self.growth_rates > 0))


def vibration_modes(model, t: float, count: int = 6) -> VibrationModes:
    """The ``count`` lowest natural frequencies and modes of a dynamic RodModel (or
    RodSystem) about its current state under time t's loads; with follower loads or
    couples the non-symmetric K (non-conservative: flutter, a complex pair of omega^2, is found).
    Raises ValueError for a quasi-static rod (density = 0: no mass)."""
    if not model.dynamic:
        raise ValueError("vibration modes: a rod with mass (density > 0: "
                         "RodParameters.density or a scene's material.density)")
    tangent = TangentStiffness(model)
    general = non_conservative(model)
    K = tangent.matrix(t, symmetric=not general)
    _warn_unless_equilibrium(tangent.unbalanced(), model.problem.force_scale(), t)
    M = _mass(tangent)
    scale = K.norm(PETSc.NormType.INFINITY) / M.norm(PETSc.NormType.INFINITY)
    pairs = eigenpairs(K, M, count, target=-1e-8 * scale,
                       kind="general" if general else "symmetric")
    K.destroy()
    M.destroy()
    complex_pair = np.abs(pairs.imaginary) > 1e-10 * scale
    values = np.where(np.abs(pairs.values) < 1e-10 * scale, 0.0, pairs.values)
    root = np.sqrt(values + 1j * np.where(complex_pair, pairs.imaginary, 0.0))
    omega = np.where(complex_pair, root.real, np.sign(values) * np.sqrt(np.abs(values)))
    growth = np.where(complex_pair, np.abs(root.imag), 0.0)
    order = np.lexsort((-np.sign(pairs.imaginary), omega))
    shapes = tangent.mode_shapes(pairs.vectors)
    return VibrationModes(t, values[order], omega[order], omega[order] / (2 * np.pi),
                          [shapes[k] for k in order], pairs.residuals[order],
                          np.where(complex_pair, pairs.imaginary, 0.0)[order],
                          growth[order])


UNBALANCED = 1e-6    # of the force scale: a run settled at rest is within Newton's 1e-10


def _warn_unless_equilibrium(unbalanced: float, scale: float, t: float) -> None:
    """A warning if the state's forces at rest are out of balance by more than UNBALANCED
    times the force scale (a moving rod: the modes are of no motion about it)."""
    if unbalanced > UNBALANCED * scale:
        warnings.warn(f"vibration modes at t = {t:g}: the state is not an equilibrium (its "
                      f"forces at rest are out of balance by {unbalanced:.3g}, "
                      f"{unbalanced / scale:.2g} of the force scale {scale:.3g}): small "
                      "motions about it are not the modes computed; run the scene until "
                      "it is at rest (damping, or a quasi-static start: initial.equilibrium)",
                      stacklevel=3)


def _mass(tangent: TangentStiffness) -> PETSc.Mat:
    """M = dR/d(accelerations) of the tangent's blocks, symmetric part, Dirichlet rows
    and columns zero (multipliers: zero rows; joints: P^T M P).  Its kernels are
    compiled once per structure (form_cache, as the tangent's): a search over loads
    (Beck's column, tests/test_vibration.py) builds its forms once."""
    model = tangent.model
    accelerations, swap = _accelerations(model, tangent.names)
    at_rest = {f: g for f, g in at_rest_map(model).items()
               if not any(f is a for a in [*accelerations, *swap])}
    residuals = [model.residual[n] for n in tangent.names]
    fields = [model.f[n] for n in tangent.names]
    key = form_cache.structure_key(residuals, "mass", tangent.names) \
        if monolithic_layout(fields) else None
    forms = None if form_cache.lookup(key, model.mesh.comm) else \
        [ufl.replace(F, {**at_rest, **swap}) for F in residuals]
    objects = [*form_cache.registry(residuals), *at_rest.values()]
    bcs = [bc for n in tangent.names for bc in model.bcs_of(n)]
    system = block_system(forms, [fields, accelerations], jacobian_terms=((1.0, 1),),
                          bcs=bcs, cache=(key, objects))
    system.get(0, system.x)
    system.set(0, system.x)
    system.jacobian(system.A)
    M = system.A
    if isinstance(tangent.system, ConstrainedSystem):
        M = M.PtAP(tangent.system.P)
    return symmetric_part(M, tangent.fixed, 0.0)


def _accelerations(model, names: list[str]) -> tuple[list, dict]:
    """Per block of ``names`` the Function the mass differentiates by, and what replaces
    the residual's accelerations: rotation vectors, the accelerations themselves; the
    quaternion form, x_tt and the rate of W = 2 vec(conj(q) q_t)/|q|^2 at rest,
    2 vec(conj(q) q_tt)/|q|^2 (its kinematic equations; the multipliers' own, unused)."""
    problem = model.problem
    if model.unknowns.chart is not None:
        given = dict(zip(model.names, problem.accelerations))
        if any(given.get(n) is None for n in names):
            raise ValueError("vibration modes: every position and rotation block needs an "
                             "acceleration (a dynamic rod with rotary inertia)")
        return [given[n] for n in names], {}
    own = {n: fem.Function(model.f[n].function_space) for n in names}
    swap = {model.r["velocity"]: own["displacement"],
            model.r["angular_velocity"]: material_derivative_vector(
                model.f["quaternion"], own["quaternion"])}
    return [own[n] for n in names], swap
