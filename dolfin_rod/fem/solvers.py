"""PETSc SNES on blocked forms (assembly.block_system), with failure reasons.

Blocks may include real spaces (global scalar unknowns; compat.real_space), so the uniform
variant's natural strains are solved monolithically with the fields, serially and under MPI.
"""

from __future__ import annotations

import functools
import itertools
import math
import time
import weakref
from typing import Callable

import dolfinx.fem as fem
import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

from ..checks import (NEWTON_ATOL, NEWTON_FORCE_CAP, NEWTON_FORCE_TOL, NEWTON_RTOL,
                      probed_options)
from . import compat
from .assembly import block_system
from .multipoint import ConstrainedSystem

_REASONS = {v: k for k, v in vars(PETSc.SNES.ConvergedReason).items() if isinstance(v, int)}
DEFAULT_OPTIONS = {
    "snes_type": "newtonls",
    "snes_linesearch_type": "basic",
    "snes_rtol": NEWTON_RTOL,
    "snes_atol": NEWTON_ATOL,
    "snes_stol": 1e-10,  # |dx| < 1e-10 |x|: converged (x then exact to ~|dx|^2); a
                         # residual floor alone cannot be met at round-off on fine meshes
    "snes_max_it": 25,
    "ksp_type": "preonly",
    "pc_type": "lu",
}
# The default LU: SuperLU on one rank (partial pivoting, so the multipliers' zero
# diagonals need no heuristic; 1.3-1.6x cheaper than MUMPS on the quaternion rods and the
# torsion model from 8 to 512 cells, docs/performance.md), MUMPS on several ranks.
DEFAULT_LU = {"serial": "superlu", "parallel": "mumps"}
# PETSc's own LU, one rank only: 5-8x cheaper factorisations than MUMPS on the rods'
# banded systems, 16 to 4096 cells (docs/performance.md).  It does not pivot: the zero
# diagonals of the multipliers (gauge, constraints) are permuted off the diagonal first,
# a heuristic (with the "qmd" ordering it crashed PETSc 3.22 on a dynamic rod), hence
# opt-in, for benchmarked model classes.  Use as BlockSNES/TimeStepper solver_options.
NATIVE_LU = {
    "pc_factor_mat_solver_type": "petsc",
    "pc_factor_mat_ordering_type": "rcm",
    "pc_factor_nonzeros_along_diagonal": 1e-12,
}
# Modified Newton for dynamics with small steps: the Jacobian and its LU are refreshed
# every 10 iterations and kept across time steps; 3-4x cheaper steps from 1e3 cells
# (docs/performance.md).  Large quasi-static load steps diverge with a stale Jacobian.
# Use as BlockSNES/TimeStepper solver_options.
JACOBIAN_REUSE = {
    "snes_lag_jacobian": 10,
    "snes_lag_jacobian_persists": True,
    "snes_lag_preconditioner": 10,
    "snes_lag_preconditioner_persists": True,
}
# BlockSNES's Jacobian rule (option jacobian_reuse_ratio): a new Jacobian and LU at each
# solve's first iteration, kept while every iteration reduces the residual norm 10-fold
# (a kept one's step to a residual above the solve's highest is taken again with a new one).
# Dynamic rods: 1.0-1.5 Jacobians per step instead of 1.9-2.6; quasi-static roll-up in
# 10 load steps: 15-20 % less time than full Newton (docs/performance.md).
REUSE_RATIO = 0.1
_ids = itertools.count()
# The SNES options of Newton as BlockSNES runs it itself (_plain_newton): SNES newtonls
# with the basic line search (full steps), its tolerances, and the Jacobian rule
# (jacobian_reuse_ratio, which asks for a Jacobian every iteration: lag 1).  Given any
# other SNES option (a monitor, a viewer, another type or line search, snes_lag_*, ...),
# SNES solves; KSP, PC and matrix options are the KSP's, which both use.
PLAIN_NEWTON = {"snes_type": "newtonls", "snes_linesearch_type": "basic", "snes_rtol": None,
                "snes_atol": None, "snes_stol": None, "snes_max_it": None,
                "snes_divergence_tolerance": None, "snes_lag_jacobian": "1",
                "snes_lag_preconditioner": "1"}


def plain_newton(settings: dict) -> bool:
    """Whether the PETSc options ``settings`` set no SNES option but PLAIN_NEWTON's (with
    its values where it names one)."""
    return all(k in PLAIN_NEWTON and PLAIN_NEWTON[k] in (None, str(v).lower())
               for k, v in settings.items() if k.startswith("snes_"))


def default_lu(comm) -> str:
    """The default LU's solver type on ``comm`` (DEFAULT_LU)."""
    return DEFAULT_LU["serial" if comm.size == 1 else "parallel"]


def petsc_options(comm, options: dict | None) -> dict:
    """DEFAULT_OPTIONS and the default LU (DEFAULT_LU, for pc_type lu only) updated by
    ``options``; PETSc's LU on several ranks is an error."""
    merged = {**DEFAULT_OPTIONS, **(options or {})}
    if merged.get("pc_type") == "lu":
        merged.setdefault("pc_factor_mat_solver_type", default_lu(comm))
    if comm.size > 1 and merged.get("pc_type") == "lu" and \
            merged.get("pc_factor_mat_solver_type") == "petsc":
        raise ValueError("pc_factor_mat_solver_type 'petsc' (NATIVE_LU) is serial; under "
                         "MPI use 'mumps' or 'superlu_dist'")
    return merged


def option_problem(options: dict) -> tuple[str, str] | None:
    """(name, reason) of the first option PETSc rejects (a value or type it does not
    know) or never reads (a name no SNES, its line search, KSP or PC knows, nor a TS if
    ts_ options are given), tried on a throwaway solver of one rank; None if all are
    fine.  Options read only later (checks.LATE_OPTIONS, *_view*) are not judged
    (checks.probed_options)."""
    def rejected(subset: dict) -> str | None:
        prefix = f"dolfin_rod_probe_{next(_ids)}_"
        opts = PETSc.Options()
        for k, v in subset.items():
            opts[prefix + k] = v
        ts = any(k.startswith("ts_") for k in subset)
        solver = (PETSc.TS() if ts else PETSc.SNES()).create(PETSc.COMM_SELF)
        solver.setOptionsPrefix(prefix)
        try:
            solver.setFromOptions()
            unread = [k for k in subset if not _used(prefix + k)]
        except PETSc.Error as err:
            return f"PETSc rejects it (error code {err.ierr}: an unknown type or a value " \
                   "of the wrong kind)"
        finally:
            solver.destroy()
            _forget_options(prefix, list(subset))
        return UNREAD if unread else None

    judged = probed_options(options)
    if not judged or rejected(judged) is None:
        return None
    for k, v in judged.items():         # which one: each alone
        reason = rejected({k: v})
        if reason is not None:
            return k, reason
    return next(iter(judged)), "PETSc rejects this combination of options"


UNREAD = "not an option that PETSc's SNES, KSP, PC, line search or TS reads (a spelling " \
         "mistake?)"


@functools.cache
def _petsc_library():
    """The loaded PETSc library (ctypes), found in this process's memory map (Linux);
    None elsewhere."""
    import ctypes
    try:
        with open("/proc/self/maps") as maps:
            path = next(line.split()[-1] for line in maps if "libpetsc" in line)
    except (OSError, StopIteration):
        return None
    return ctypes.CDLL(path)


def _used(name: str) -> bool:
    """The option was read (PETSc's PetscOptionsUsed, which petsc4py lacks); True where
    that cannot be known."""
    import ctypes
    lib = _petsc_library()
    if lib is None:
        return True
    used = ctypes.c_int(0)
    lib.PetscOptionsUsed(None, name.encode(), ctypes.byref(used))
    return bool(used.value)


def _forget_options(prefix: str, keys: list[str]) -> None:
    opts = PETSc.Options()
    for k in keys:
        opts.delValue(prefix + k)


def default_test(snes, it: int, norms, fnorm0: float, step_scale: float = 0.0,
                 force_scale: float = 0.0, static: bool = False) -> int:
    """PETSc's default test (NewtonTest) at SNES's ``norms`` (|y|, |dy|, |F|) of
    iteration ``it``; ``fnorm0`` the solve's initial residual norm."""
    xnorm, ynorm, fnorm = norms
    return NewtonTest(snes, fnorm0, step_scale, force_scale, static)(
        it, fnorm, lambda: (xnorm, ynorm))


def relative_reference(fnorm0: float, force_scale: float, static: bool) -> float:
    """What snes_rtol is relative to: the first residual norm ``fnorm0``; for a
    ``static`` residual (no inertia: a quasi-static step, a settled start) at most the
    problem's ``force_scale`` (0: unknown).  A static step's first residual can lie far
    above the forces (a segment pair deep in its barrier at the linear predictor: 4.8e8
    against a 0.4 N load), and rtol 1e-8 of it accepted 0.76 N, a state off equilibrium
    by more than the load (tests/test_force_scale.py).  A dynamic step's first residual
    is the inertia's, mass / dt^2 times the predictor's error, which the relative test
    is meant to reduce: relative to the forces it asked the 2-rank iterative linear
    solver (lie_alpha.default_options) for more than it gives (DIVERGED_LINEAR_SOLVE
    after 6 cuts, tests/test_thin_obstacle.py), so it keeps the first residual."""
    return min(fnorm0, force_scale) if static and force_scale > 0.0 else fnorm0


def relative_tolerance(rtol: float, fnorm0: float, force_scale: float,
                       static: bool) -> float:
    """The residual norm the relative test accepts: snes_rtol times relative_reference,
    at most NEWTON_FORCE_CAP times the ``force_scale`` (0: unknown, no cap).  The cap
    bites in dynamic steps whose first residual is dominated by something other than the
    inertia of the predictor's error: the stiff axial rows of a stiff pendulum (a 1 cm
    hair, EA / EI ~ 1e9: rtol 1e-4 of its first residual accepted 3.2 times the force
    scale, 6 times its weight, and the swing ended at tip x/L -0.52 against -0.90;
    capped: within 5e-4 L of rtol 1e-14's in SI, mm-N-ms and pN-nm-ns,
    tests/test_force_scale.py), a barrier at the predictor (a rod thrown at a thin
    obstacle: Newton stopped at 31 N, the force scale 0.05 N).  1e-3 leaves the peer
    benchmark's steps as they were (soft, creep, 6 to 64 cells: the same iterations and
    tips; 1e-4 moved soft at 6 cells; 1e-2 left the pendulum 2.6e-3 L off in mm-N-ms,
    where the force scale, the stiffness floor E I / L^2, is 200 times the weight)."""
    tolerance = rtol * relative_reference(fnorm0, force_scale, static)
    return min(tolerance, NEWTON_FORCE_CAP * force_scale) if force_scale > 0.0 else tolerance


class NewtonTest:
    """PETSc's default convergence test (SNESConvergedDefault: NaN, atol, rtol, step,
    divergence; snes_max_it is the caller's check) of one solve, with |y| + step_scale
    in the step test, max(fnorm0, force_scale) in the divergence test |F| >
    snes_divergence_tolerance max(...) (a small first residual, a load increment, against
    the residual's rows of the problem's size: ForceScale) and, for a ``static``
    residual (no inertia), the relative test against at most the force scale
    (relative_reference); ``fnorm0`` the solve's initial residual norm.  The tolerances
    are read, and the relative and divergence thresholds computed, once per solve (at
    its first residual: BlockSNES's own Newton loop tests every iteration with one
    object); a call tests iteration ``it``'s residual norm ``fnorm`` and takes the step
    test's norms (|y|, |dy|) from ``step_norms()`` only when that test is reached."""

    def __init__(self, snes, fnorm0: float, step_scale: float = 0.0,
                 force_scale: float = 0.0, static: bool = False):
        rtol, self.atol, self.stol, self.max_it = snes.getTolerances()
        self.relative = relative_tolerance(rtol, fnorm0, force_scale, static)
        divtol = snes.getDivergenceTolerance()
        self.divergence = divtol * max(fnorm0, force_scale) if divtol > 0 else math.inf
        self.step_scale = step_scale

    def __call__(self, it: int, fnorm: float, step_norms) -> int:
        reasons = PETSc.SNES.ConvergedReason
        if not math.isfinite(fnorm):      # (a float: math's test, 1 us less than numpy's)
            return compat.NONFINITE_NORM
        if fnorm < self.atol:
            return reasons.CONVERGED_FNORM_ABS
        if it == 0:
            return reasons.ITERATING
        if fnorm <= self.relative:
            return reasons.CONVERGED_FNORM_RELATIVE
        xnorm, ynorm = step_norms()
        if ynorm < self.stol * (xnorm + self.step_scale):
            return reasons.CONVERGED_SNORM_RELATIVE
        if fnorm > self.divergence:       # (inf without a divergence tolerance)
            return reasons.DIVERGED_DTOL
        return reasons.ITERATING


def residual_problem(snes, reason: int, norm: float, initial: float,
                     floor: float = 0.0, force_scale: float = 0.0,
                     static: bool = False) -> str | None:
    """Why a solve SNES reports as converged (``reason``) is not one, or None: the
    residual ``norm`` at the solution must meet snes_atol or the relative test's
    tolerance (relative_tolerance: snes_rtol times the ``initial`` norm, at most
    ``force_scale`` if ``static``, at most NEWTON_FORCE_CAP times it); after the step
    test it must not have grown (or be at most the round-off ``floor``: Newton stopped
    moving there)."""
    rtol, atol, _, _ = snes.getTolerances()
    tolerance = max(atol, relative_tolerance(rtol, initial, force_scale, static))
    if norm <= tolerance:
        return None
    if reason == PETSc.SNES.ConvergedReason.CONVERGED_SNORM_RELATIVE and \
            norm <= max(initial, floor):
        return None
    reference = "the initial norm, at most the force scale" if static else "the initial norm"
    return (f"{_REASONS.get(reason, reason)} but the residual norm at the solution is "
            f"{norm:.3g}, above the tolerance {tolerance:.3g} (snes_atol, or snes_rtol "
            f"times {reference}, at most {NEWTON_FORCE_CAP:g} times the force scale; "
            "check the solver options)")


class ForceScale:
    """A solve's force scale: the problem's ``force_scale()`` (the size of the residual's
    forces at the time the problem was last set to, in its units: fem/problem.py; a
    rod's rod/force_scale.py), taken at each solve's start (``start``).  Newton's
    absolute test then follows the forces, snes_atol = NEWTON_FORCE_TOL times it, at
    most NEWTON_ATOL (also where it is 0: unknown), unless the PETSc ``options`` give
    snes_atol (then exactly that); the divergence test compares with max(the initial
    norm, it) (newton_test).  At most NEWTON_ATOL: the scale's floor, the stiffness force
    F*, can lie far above the loads (an L-frame of EI ~ 1e3 under 1e-6 N: 1e-7 would
    leave its knee force 1e-10 off, 1e-4 of the load: tests/test_joints.py); above
    NEWTON_ATOL Newton stops by the relative or the step test (unit-free) as before.
    ``static``: the residual has no inertia (a quasi-static step, a settled start): the
    relative test is against at most the scale too (relative_reference)."""

    def __init__(self, force_scale: Callable[[], float], options: dict | None,
                 static: bool = False):
        self.force_scale = force_scale
        self.atol_given = "snes_atol" in (options or {})
        self.static = static
        self.value = 0.0

    def start(self, snes) -> None:
        self.value = self.force_scale()
        if not self.atol_given:
            snes.setTolerances(atol=min(NEWTON_FORCE_TOL * self.value, NEWTON_ATOL)
                               if self.value > 0.0 else NEWTON_ATOL)


# SNES types that stop without a convergence test (their last monitor call has the
# residual at the solution)
UNTESTED_TYPES = ("ksponly", "ksptransposeonly")


def scale_terms(scale: ForceScale | None) -> tuple[float, bool]:
    """(force scale, static) of a solve for newton_test and residual_problem: (0, False)
    without a ForceScale."""
    return (scale.value, scale.static) if scale is not None else (0.0, False)


class CheckedSNES:
    """The residual check of BlockSNES for a SNES driven by others (PETSc TS's stage
    solves): a solve it reports as converged whose residual at the solution misses the
    tolerances (residual_problem) is turned into DIVERGED_DTOL, which TS treats as a
    failed solve (step rejected, cut, IntegrationError after its rejections);
    ``failure`` keeps the last such message.  The convergence test is PETSc's default
    (default_test) plus the check, also under snes_convergence_test options; types
    without a test (UNTESTED_TYPES) are checked at their last monitor call.  The
    residual norm is the one SNES computed at the iterate: no extra assembly.
    ``scale``: the problem's ForceScale, taken at each stage solve's start."""

    def __init__(self, snes, scale: ForceScale | None = None):
        self.snes, self.failure, self._initial = snes, None, np.inf
        self.scale = scale
        snes.setConvergenceTest(self._converged)
        snes.setMonitor(self._monitor)

    def _start(self, snes, fnorm: float) -> None:
        self._initial = fnorm
        if self.scale is not None:
            self.scale.start(snes)

    def _monitor(self, snes, it: int, fnorm: float) -> None:
        if it == 0:
            self._start(snes, fnorm)
        elif snes.getType() in UNTESTED_TYPES:
            snes.setConvergedReason(self._checked(snes.getConvergedReason(), fnorm))

    def _converged(self, snes, it: int, norms) -> int:
        if it == 0:
            self._start(snes, norms[2])
        reason = default_test(snes, it, norms, self._initial, 0.0, *scale_terms(self.scale))
        return self._checked(reason, norms[2]) if reason > 0 else reason

    def _checked(self, reason: int, norm: float) -> int:
        if reason <= 0:
            return reason
        problem = residual_problem(self.snes, reason, norm, self._initial, 0.0,
                                   *scale_terms(self.scale))
        if problem is None:
            return reason
        self.failure = problem
        return PETSc.SNES.ConvergedReason.DIVERGED_DTOL


# PETSc's own LU declares a pivot below 100 machine epsilons zero, whatever the matrix's
# units (PCFactorSetZeroPivot); zero_pivot scales it down with a small matrix
PETSC_ZERO_PIVOT = 100 * np.finfo(float).eps


def zero_pivot(A) -> float:
    """The zero-pivot tolerance of an LU of A: PETSC_ZERO_PIVOT times its smallest nonzero
    diagonal entry's magnitude where that is below 1 (e.g. 6e-18 for a 100 nm rod's
    couple rows in SI, 8e-18 for a hair's rotary inertia, whose every pivot PETSc's
    default would call zero), else PETSc's own: the same factorizations for every matrix
    of entries >= 1, and unit-free below."""
    diagonal = np.abs(A.getDiagonal().getArray(readonly=True))
    local = float(diagonal[diagonal > 0].min(initial=np.inf))
    smallest = A.getComm().tompi4py().allreduce(local, op=MPI.MIN)
    return PETSC_ZERO_PIVOT * min(1.0, smallest)


class SolverError(RuntimeError):
    """SNES did not converge; ``reason`` is PETSc's converged-reason name."""

    def __init__(self, reason: str, iterations: int):
        super().__init__(f"SNES failed: {reason} after {iterations} iterations")
        self.reason = reason
        self.iterations = iterations


class BlockSNES:
    """Solve F_i(y) = 0 (one form per block) for the block Functions ``y`` with SNES.

    ``options`` are PETSc options under a private prefix (defaults: Newton without a
    line search and an LU, SuperLU on one rank and MUMPS on several: DEFAULT_LU).
    ``cache``: (key, objects) to share compiled forms (assembly.block_system).
    ``terms``: residual and Jacobian terms that are not forms (assembly's add_terms);
    a term's ``limit_step(x, y)`` may shorten each Newton update (a pre-check of the line
    search: segment contact keeps pairs from passing through each other).
    ``force_scale``: the problem's (fem/problem.py), taken at each solve's start
    (ForceScale): without snes_atol in ``options`` snes_atol is NEWTON_FORCE_TOL times
    it (unit-free; a given snes_atol is used as it is), and the divergence test compares
    with max(initial norm, it).  ``static``: F has no inertia (a quasi-static step, a
    settled start; fem/problem.py's ``inertia``): snes_rtol is relative to min(initial
    norm, force scale) (relative_reference), so a first residual far above the forces
    (a contact barrier's) cannot make the relative test accept a residual of the loads'
    size.
    ``step_scale``: for unknowns without a size of their own (a rod's displacements and
    rotation increments: 0 at rest) the norm of a configuration of the problem's size,
    added to |y| in the step test |dy| < snes_stol (|y| + step_scale) (_converged; 0:
    PETSc's test, |dy| < snes_stol |y|).  Without it Newton at a residual's round-off
    floor (stiff axial terms: E A eps, above a small load's snes_rtol) only stops at
    snes_max_it, where the quaternion rod, whose unit quaternions are part of |y|, stops.

    Option ``linesearch_fallback`` (not a PETSc option; default none): a line search type
    a solve that failed is retried with once, from the same start, before it is reported
    failed (the line search given by snes_linesearch_type is back for the next solve).
    A solve that succeeds with the first is unchanged, bit for bit.

    Option ``jacobian_reuse_ratio`` r (not a PETSc option; default REUSE_RATIO, 0: a new
    Jacobian every iteration): each solve starts with a new Jacobian and LU and keeps
    them while every Newton iteration reduces the residual norm by at least the factor
    r; after a slower iteration the next one builds a new one.  A step on a kept
    Jacobian whose residual norm is above the highest of the solve so far (its start's,
    as a rule) or not finite is taken back and taken again from its start with a new Jacobian (in
    BlockSNES's own loop, _plain_newton: the default options; under SNESSolve it stays):
    from a far start a kept Jacobian's step can leave the basin of convergence for good
    (Kirchhoff's helix held by a wrench at 32 cells, scenes/helix_wrench.toml: 256 ->
    10.6 -> 719, above the start, and DIVERGED_MAX_IT; tests/test_helices.py).  A
    step that raises the residual less is kept, as full Newton keeps its own (the same
    helix: 10.6 -> 24.6 -> 1.64 -> 18.3 -> ... converges): a non-monotone acceptance
    test (Grippo, Lampariello and Lucidi, SIAM J. Numer. Anal. 23, 1986, with the whole
    solve as its memory), which leaves a solve whose kept Jacobians never lose its
    progress unchanged, bit for bit (taking back every step that raised the residual
    moved the unstable crossing ropes of tests/test_cosseratbench.py to another settled
    state).  A solve's result depends on its start only (a resumed run equals an
    uninterrupted one).  Given PETSc snes_lag_* options (e.g. JACOBIAN_REUSE) replace
    the rule.

    A solve SNES reports as converged is checked against the residual at the solution
    (_verify_residual): it must meet snes_atol or snes_rtol (times the initial norm),
    except after a step test, where the residual must not have grown or be at most the
    residual's round-off floor (round_off_floor: Newton stopped there, e.g. 1e-8 on
    stiff rods, measured; a step that starts at the floor fluctuates there); else
    SolverError.  Options that stop without testing the residual (snes_type ksponly,
    snes_max_it with snes_convergence_test skip) thus never return a wrong answer.

    With the default options, or any that set no SNES option but those of PLAIN_NEWTON
    (tolerances; the Jacobian rule), Newton runs in this class (_plain_newton) instead
    of SNESSolve: SNES newtonls with the basic line search step for step, the same
    iterates, norms, tests and reasons, bit for bit, without SNES's per-solve set-up and
    viewers and its callbacks into Python (docs/performance.md, eleventh round); SNES's
    KSP solves the linear systems, with every KSP and PC option.  Other options
    (monitors, viewers, line searches, lags), and the fallback line search, go to SNES.
    """

    def __init__(self, F: list[ufl.Form] | None, y: list[fem.Function], bcs=(), options=None,
                 prefix: str | None = None, cache=None, step_scale: float = 0.0, links=(),
                 terms=(), force_scale: Callable[[], float] | None = None,
                 static: bool = False):
        self.y = y
        self.scale = ForceScale(force_scale, options, static) \
            if force_scale is not None else None
        settings = petsc_options(y[0].function_space.mesh.comm, options)
        lagged = any(k.startswith("snes_lag_") for k in options or {})
        self.reuse_ratio = settings.pop("jacobian_reuse_ratio",
                                        None if lagged else REUSE_RATIO)
        self.fallback = settings.pop("linesearch_fallback", None)
        if self.reuse_ratio is not None:   # PETSc asks every iteration, _jacobian decides
            settings.update(snes_lag_jacobian=1, snes_lag_preconditioner=1)
        self.system = block_system(F, [y], bcs=bcs, cache=cache)
        self.system.add_terms(terms)
        if links:       # joints: Newton on the free dofs (fem/multipoint.py)
            self.system = ConstrainedSystem(self.system, y, list(links))
        self.x = self.system.x
        self.snes = PETSc.SNES().create(self.x.getComm())
        self.snes.setFunction(self._snes_residual, self.system.b)
        self.snes.setJacobian(self._jacobian, self.system.A)
        self.prefix = prefix or f"dolfin_rod_{next(_ids)}_"
        self.snes.setOptionsPrefix(self.prefix)
        opts = PETSc.Options()
        for k, v in settings.items():
            opts[self.prefix + k] = v
        self.snes.setFromOptions()
        self._set_pre_check()
        self._ksp = self.snes.getKSP()
        self._plain = self.reuse_ratio is not None and plain_newton(settings)
        if self._plain:     # (SNES sets the same operators at each of its iterations)
            self._ksp.setOperators(self.system.A, self.system.A)
        self._update = None       # _plain_newton's update, made at its first solve
        self.step_scale = step_scale
        if step_scale > 0.0 or self.scale is not None:
            self.snes.setConvergenceTest(self._converged)
        # the options go with the solver (also at exit, before PETSc's own finalisation):
        # the sub-solver options of block Jacobi (MPI) are read at the first solve only,
        # and PETSc reports every option left unread ("WARNING! There are options you set
        # that were not used!") for a solver that never solved
        weakref.finalize(self, _forget_options, self.prefix, list(settings))
        self._settings = settings
        self._last_norm = np.inf
        self._x_at_residual, self._r = self.x.duplicate(), self.system.b.duplicate()
        self._start = self.x.duplicate() if self.fallback is not None else None
        self._residual_norm, self._initial_norm = np.inf, None
        self._bc_values = None
        # (numpy indexes with its own integer type: int32 rows cost a conversion a solve)
        self._bc_rows = np.asarray(self.system.bc_rows, dtype=np.intp)
        self._persists = tuple(str(settings.get(f"snes_lag_{k}_persists", False)).lower()
                               in ("true", "1", "yes") for k in ("jacobian", "preconditioner"))
        self.iterations = 0
        self.timings = {"residual": 0.0, "jacobian": 0.0}  # seconds spent in assembly
        self.counts = {"residual": 0, "jacobian": 0}      # assemblies

    def _snes_residual(self, snes, x, b):
        """SNES's function: _residual, and x kept (SNES also evaluates trial vectors;
        _verify_residual: the norm at the solution)."""
        self._residual(snes, x, b)
        x.copy(self._x_at_residual)

    def _residual(self, snes, x, b):
        """b = F(x) and its norm (_plain_newton's residual: always at its iterate)."""
        t0 = time.perf_counter()
        self.system.set(0, x, blocks=False)     # the block Functions: once solved
        self.system.residual(x, b, self._bc_values)
        self._residual_norm = b.norm()
        if self._initial_norm is None:
            self._initial_norm = self._residual_norm
        self.timings["residual"] += time.perf_counter() - t0
        self.counts["residual"] += 1

    def _limit_step(self, x, y) -> None:
        """The line search's pre-check: terms shorten Newton's update y (x - y)."""
        xa, ya = x.getArray(readonly=True), y.getArray()
        for term in self.system.terms:
            if hasattr(term, "limit_step"):     # (a mesh obstacle's features have none)
                term.limit_step(xa, ya)

    def _jacobian(self, snes, x, A, P):
        if self.reuse_ratio is None or self._new_jacobian_needed(snes.getIterationNumber(),
                                                                   snes.getFunctionNorm()):
            self._assemble_jacobian()
        # else A unchanged: PETSc keeps its LU as well (PCSetUp: same state)

    def _assemble_jacobian(self) -> None:
        t0 = time.perf_counter()
        changes = self.system.pattern_changes
        self.system.jacobian(self.system.A)
        if not self.counts["jacobian"]:         # the first: the matrix's scale
            self._scale_zero_pivot()
        if self.system.pattern_changes != changes:    # a new factorisation, symbolic too
            self._ksp.getPC().reset()       # (which drops the operators: set again, as
            self._ksp.setOperators(self.system.A, self.system.A)    # SNES does after this)
        self.timings["jacobian"] += time.perf_counter() - t0
        self.counts["jacobian"] += 1

    def _scale_zero_pivot(self) -> None:
        """The LU's zero-pivot tolerance from the first Jacobian (zero_pivot), unless the
        options give one: the PC's, or block Jacobi's and ASM's sub-solvers' (through the
        options database: they read it at their set-up, in the first solve)."""
        if any(k.endswith("pc_factor_zeropivot") for k in self._settings):
            return
        value, pc = zero_pivot(self.system.A), self._ksp.getPC()
        if pc.getType() in ("bjacobi", "asm"):
            PETSc.Options()[f"{self.prefix}sub_pc_factor_zeropivot"] = value
            weakref.finalize(self, _forget_options, self.prefix, ["sub_pc_factor_zeropivot"])
        else:
            pc.setFactorPivot(zeropivot=value)

    def _new_jacobian_needed(self, it: int, norm: float) -> bool:
        """jacobian_reuse_ratio: a new Jacobian at the first iteration (``it`` 0) of a
        solve and after an iteration that reduced the residual ``norm`` by less than the
        ratio."""
        last, self._last_norm = self._last_norm, norm
        return it == 0 or norm > self.reuse_ratio * last

    def _converged(self, snes, it: int, norms) -> int:
        if it == 0:
            self._fnorm0 = norms[2]
        return default_test(snes, it, norms, self._fnorm0, self.step_scale,
                            *scale_terms(self.scale))

    def _set_persists(self, flags) -> None:
        opts = PETSc.Options()
        for k, flag in zip(("jacobian", "preconditioner"), flags):
            opts[f"{self.prefix}snes_lag_{k}_persists"] = flag
        self.snes.setFromOptions()

    def solve(self, fresh_jacobian: bool = False, sub_solves: int = 1) -> int:
        """Newton from the current ``y``; on success ``y`` holds the solution.

        fresh_jacobian: start from a new Jacobian even if a lagged one persists across
        solves (JACOBIAN_REUSE): the caller knows the forms changed, e.g. a new dt.
        sub_solves: n > 1 approaches the Dirichlet values from those ``y`` holds in n
        solves (values y_bc + k/n (g - y_bc), k = 1..n, each from the last one's
        solution): the same equations at the end, a path to them from a far start (a
        prescribed rotation that jumps).  Returns the Newton iterations of all of them.
        """
        self.system.get(0, self.x)
        target = self.system.bc_values()
        start = self.x.getArray(readonly=True)[self._bc_rows]
        fresh = fresh_jacobian and any(self._persists)
        if fresh:  # (petsc4py 3.22 has no SNESSetLag*Persists: via the options database)
            self._set_persists((False, False))
        self.iterations = 0
        if self.scale is not None:
            self.scale.start(self.snes)
        try:
            path = target - start
            for k in range(1, sub_solves + 1):  # (fixed in a solve; the last factor, 1, exact)
                self._bc_values = start + (path if k == sub_solves
                                           else (k / sub_solves) * path)
                self._solve_once()
        finally:
            if fresh:
                self._set_persists(self._persists)
            self.system.set(0, self.x)
        return self.iterations

    def _solve_once(self) -> None:
        if self.fallback is None:
            return self._newton()
        self.x.copy(self._start)        # (one vector for every solve, not one a solve)
        try:
            self._newton()
        except SolverError:
            self._start.copy(self.x)
            self._with_line_search(self.fallback, self._snes_newton)

    def _with_line_search(self, kind: str, solve) -> None:
        """solve() with the line search ``kind``, then the configured one again (through
        the options database: petsc4py 3.22 has no SNESGetLineSearch; the pre-check, the
        terms' update limit, set anew after each change)."""
        opts, key = PETSc.Options(), f"{self.prefix}snes_linesearch_type"
        configured = opts.getString(key, "basic")
        try:
            opts[key] = kind
            self.snes.setFromOptions()
            self._set_pre_check()
            solve()
        finally:
            opts[key] = configured
            self.snes.setFromOptions()
            self._set_pre_check()

    def _set_pre_check(self) -> None:
        if self._limits_step():
            self.snes.setLineSearchPreCheck(self._limit_step)

    def _limits_step(self) -> bool:
        return any(hasattr(term, "limit_step") for term in self.system.terms)

    def _newton(self) -> None:
        if self._plain:
            self._plain_newton()
        else:
            self._snes_newton()

    def _snes_newton(self) -> None:
        self._initial_norm = None
        self.snes.solve(None, self.x)
        self._outcome(self.snes.getConvergedReason())

    def _outcome(self, reason: int, at_solution: bool = False) -> None:
        """The solve's iterations counted; SolverError unless it converged to a residual
        that meets the tolerances (_verify_residual; ``at_solution``: the last residual
        was evaluated at the solution, as _plain_newton's always is)."""
        self.iterations += self.snes.getIterationNumber()
        if reason == PETSc.SNES.ConvergedReason.DIVERGED_LINEAR_SOLVE:
            # a failed factorisation (a zero pivot at one bad iterate) must not fail the
            # next solves: block Jacobi (the 2-rank dynamic default) kept PC_SUBPC_ERROR
            # and every later solve, the step cuts' too, failed at its first iteration
            # (tests/test_thin_obstacle.py on 2 ranks, with the force cap)
            self._ksp.getPC().setFailedReason(PETSc.PC.FailedReason.NOERROR)
        if reason <= 0 or not math.isfinite(self.snes.getFunctionNorm()):
            raise SolverError(_REASONS.get(reason, str(reason)), self.iterations)
        self._verify_residual(reason, at_solution)

    def _plain_newton(self) -> None:
        """SNESSolve_NEWTONLS with the basic line search (PETSc 3.22 and 3.25) without
        SNES: x <- x - J^-1 F(x) (J by the Jacobian rule, solved by SNES's KSP; the
        terms' update limit as the line search's pre-check) until the convergence test
        (NewtonTest: PETSc's default with the step scale), snes_max_it
        (DIVERGED_MAX_IT), a failed linear solve (DIVERGED_LINEAR_SOLVE) or a non-finite
        residual norm (compat.NONFINITE_NORM) stops it; SNES's reason, iteration count
        and residual norm are then set as SNESSolve leaves them.  Unlike SNESSolve, a
        step on a kept Jacobian to a residual norm above the solve's highest is taken
        back and taken again with a new Jacobian (not counted as an iteration; the
        Jacobian rule)."""
        snes, ksp, x, b = self.snes, self._ksp, self.x, self.system.b
        if self._update is None:
            self._update, self._step_start = x.duplicate(), x.duplicate()
        dx, start, limits = self._update, self._step_start, self._limits_step()
        self._initial_norm = None
        self._residual(snes, x, b)
        fnorm = self._residual_norm
        test = NewtonTest(snes, fnorm, self.step_scale, *scale_terms(self.scale))

        def step_norms():
            return x.norm(), dx.norm()

        it, reason, retake, highest = 0, test(0, fnorm, step_norms), False, fnorm
        reasons = PETSc.SNES.ConvergedReason
        while not reason:
            if it == test.max_it:
                reason = reasons.DIVERGED_MAX_IT
                break
            fresh = self._new_jacobian_needed(it, fnorm) or retake
            if fresh:
                self._assemble_jacobian()
            else:
                x.copy(start)
            ksp.solve(b, dx)
            if ksp.getConvergedReason() < 0:
                reason = reasons.DIVERGED_LINEAR_SOLVE
                break
            if limits:
                self._limit_step(x, dx)
            x.axpy(-1.0, dx)
            self._residual(snes, x, b)
            retake = not fresh and not self._residual_norm <= highest
            if retake:      # the kept Jacobian lost the solve's progress: the step taken
                start.copy(x)               # back, and taken again with a new one
                self._residual(snes, x, b)  # (b and the forms' state at its start)
                continue
            fnorm = self._residual_norm
            highest = max(highest, fnorm)
            if not math.isfinite(fnorm):
                reason = compat.NONFINITE_NORM
                break
            it += 1
            reason = test(it, fnorm, step_norms)
        snes.setConvergedReason(reason)
        snes.setIterationNumber(it)
        snes.setFunctionNorm(fnorm)
        self._outcome(reason, at_solution=True)

    def round_off_floor(self) -> float:
        """The order of the residual norm's round-off floor, eps || |J| (|y| + h) ||: a
        residual entry sums terms of the size stiffness x strain-like quantity of order
        one (a unit tangent, unit directors), which cancel to the (much smaller) load;
        the Jacobian's entries are stiffness / h, so |J| times the cell size h (the change
        of a position across a cell at unit strain) is the terms' size, row by row; and
        the unknowns carry their own rounding, eps |y|, which |J| turns into the rows'
        (a ring: displacements from the straight reference of the order of its length,
        unit quaternions; its residual at an equilibrium is 1.0e-9 at 32 cells, 1.1e-8
        at 128, above eps || |J| h || = 8.6e-10, 1.7e-9, and below this estimate,
        1.1e-8, 8.5e-8; tests/test_ring.py).  An upper estimate: on the column of
        benchmarks/stability_check.py (B = 1e5..3e5, 32-256 cells, |y| ~ 1e-6) the
        residual fluctuates at 1e-11..1e-10, 20-100x below it, above an snes_atol of
        1e-11 (tests/test_solvers_floor.py).  Uses the last assembled Jacobian (its
        size, not its exactness, matters); computed only when a step test's residual
        grew; 0 before any Jacobian."""
        A = self.system.A
        if not A.assembled:
            return 0.0
        rows, columns, values = A.getValuesCSR()        # owned rows, global columns
        size = A.createVecRight()
        self.x.copy(size)
        size.abs()
        size.shift(self._cell_size())
        magnitudes = PETSc.Mat().createAIJ(A.getSizes(), csr=(rows, columns, np.abs(values)),
                                           comm=A.getComm())
        terms = A.createVecLeft()
        magnitudes.mult(size, terms)
        floor = float(np.finfo(float).eps * terms.norm())
        for work in (magnitudes, size, terms):
            work.destroy()
        return floor

    def _cell_size(self) -> float:
        """The mesh's extent (bounding-box diagonal over all ranks) over its cells."""
        mesh = self.y[0].function_space.mesh
        comm = mesh.comm
        x = mesh.geometry.x
        low, high = np.empty(x.shape[1]), np.empty(x.shape[1])
        comm.Allreduce(x.min(axis=0), low, op=MPI.MIN)
        comm.Allreduce(x.max(axis=0), high, op=MPI.MAX)
        cells = mesh.topology.index_map(mesh.topology.dim).size_global
        return float(np.linalg.norm(high - low)) / cells

    def _verify_residual(self, reason: int, at_solution: bool = False) -> None:
        """SNES reported convergence: the residual at the solution must meet the
        tolerances, whatever the options (ksponly, a loose linear solve, a convergence
        test that trusts a small step); else SolverError with the norms.  The residual
        is evaluated at the solution first unless ``at_solution`` or the last one was
        there."""
        if not at_solution and not self.x.equal(self._x_at_residual):
            self.snes.computeFunction(self.x, self._r)   # -> _snes_residual at the solution
        norm, initial = self._residual_norm, self._initial_norm
        floor = self.round_off_floor() if norm > initial and \
            reason == PETSc.SNES.ConvergedReason.CONVERGED_SNORM_RELATIVE else 0.0
        problem = residual_problem(self.snes, reason, norm, initial, floor,
                                   *scale_terms(self.scale))
        if problem is not None:
            raise SolverError(problem + ",", self.iterations)
