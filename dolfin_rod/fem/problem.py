"""The semi-discrete problem: physics written once as F(t, y, dy/dt; v) = 0.

A model (torsion, 3-D rod) builds a :class:`SemiDiscreteProblem`; an integrator turns
it into the residual of one time step; a solver solves that.  Three places that meet in
one line (after dolfiny): the model never sees dt, the integrator never sees
the physics, the solver never sees time.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import dolfinx.fem as fem
import numpy as np
import ufl
from mpi4py import MPI

from ..checks import STARTING_ACCELERATIONS, one_of


@dataclass
class TimeDependentValue:
    """A fem.Constant in the residual whose value is a function of time (a load)."""

    constant: fem.Constant
    history: Callable[[float], float | np.ndarray]

    def __post_init__(self):
        # the Constant's values, fetched once (its ``value`` property costs ~1.5 us)
        self._values = self.constant.value

    def at(self, t: float) -> np.ndarray:
        return np.asarray(self.history(t), dtype=float).reshape(self._values.shape)

    def set(self, t: float) -> None:
        """The constant's value at t."""
        self._values[...] = self.at(t)


@dataclass
class SemiDiscreteProblem:
    """F(t, y, dy/dt; v) = 0 on a blocked (ufl.MixedFunctionSpace-like) space.

    fields:    y, one Function per block: the unknowns, updated in place by integrators.
    rates:     placeholders for dy/dt in ``residual`` (same spaces as ``fields``).
    residual:  one UFL form per block, linear in the block's test function.
    loads:     constants in ``residual`` set from their histories at each evaluation time.
    bcs:       Dirichlet conditions on the blocks of ``fields``.
    set_bcs:   sets the prescribed values of ``bcs`` (and their rates) at time t.
    after_step:  called after an accepted step, with its state in fields/rates, to update
                 what the model derives from them (e.g. a rod's stored rotations).
    check_step:  called when a step's Newton has converged (its state in fields): a
                 reason to reject the step (it is then redone smaller), or None; e.g. a
                 rotation increment no resolved step makes (a spurious root).
    links:       linear multi-point constraints between nodes (fem/multipoint.NodeLink:
                 joints of a rod system), eliminated by the solvers.
    unset_state: what to call before integrating ("": the state is set); a model whose
                 fields start invalid (a rod's zero quaternions) names its set-up call.
    prescribed_motions: {name: t -> value} the prescribed motions of a body with inertia,
                 which the steps must resolve (integrators' check_run: no jump, no change
                 faster than dt; loads.resolution_problem).
    structure:   the residual's structure as data (None: unknown), equal for two problems
                 whose residuals differ only in the values of their Constants and
                 Functions (rod/structure.py): the integrators' compiled kernels are
                 found by it without UFL signatures (fem/form_cache.structure_key).
    terms:       residual and Jacobian terms that are not forms, evaluated at the
                 unknowns of the solve (fem/assembly add_terms: a rod's segment contact);
                 only integrators that solve for the fields at the step's end take them.
    where_failed: a description of where a step that finally failed went wrong (a rod's
                 segment pair nearest to touching), or None; added to the integrators'
                 IntegrationError.
    force_scale: the size of the residual's forces at the time of the last set_bcs, in
                 its units (a rod's: rod/force_scale.py), 0 if unknown: Newton's absolute
                 tolerance is checks.NEWTON_FORCE_TOL times it unless snes_atol is given
                 (solvers.BlockSNES); 0: snes_atol's default, checks.NEWTON_ATOL.
    start_loaded: the fields hold an equilibrium with the loads at their time, not a
                 state given unloaded: a settled start (rod/initial_state.settle), a state
                 read from a run (output/from_run.py).  A quasi-static stepper's first step
                 then approaches its loads on a load path from those at its start, not
                 from none (integrators/stepper.py); the state's setters set it.
    inertia:     the residual has a mass term (a dynamic body; the default).  False (a
                 quasi-static rod): the step's Newton is static, snes_rtol relative to
                 at most force_scale (solvers.relative_reference: a first residual
                 dominated by a contact barrier cannot accept a state off equilibrium).
    """

    fields: list[fem.Function]
    rates: list[fem.Function]
    residual: list[ufl.Form]
    loads: list[TimeDependentValue] = field(default_factory=list)
    bcs: list[fem.DirichletBC] = field(default_factory=list)
    set_bcs: Callable[[float], None] = lambda t: None
    after_step: Callable[[], None] = lambda: None
    check_step: Callable[[], str | None] = lambda: None
    links: list = field(default_factory=list)
    unset_state: str = ""
    prescribed_motions: dict = field(default_factory=dict)
    structure: str | None = None
    terms: list = field(default_factory=list)
    where_failed: Callable[[], str | None] = lambda: None
    force_scale: Callable[[], float] = lambda: 0.0
    inertia: bool = True
    start_loaded: bool = False

    def __post_init__(self):
        if not (len(self.fields) == len(self.rates) == len(self.residual)):
            raise ValueError("fields, rates and residual must have one entry per block")

    @property
    def comm(self):
        return self.fields[0].function_space.mesh.comm

    def configuration_norm(self) -> float:
        """The norm of a configuration of the problem's size for Newton's step test
        (solvers.BlockSNES step_scale); 0: the unknowns carry their own size."""
        return 0.0

    def set_loads(self, t: float) -> None:
        for load in self.loads:
            load.set(t)

    def scale_loads(self, factor: float) -> None:
        """The loads' values as set last (set_loads) times ``factor``: a part of them on
        a load path (integrators/lie_alpha.py: a quasi-static start approached in
        parts)."""
        for load in self.loads:
            load.constant.value[...] *= factor


@dataclass
class SecondOrderProblem(SemiDiscreteProblem):
    """F(t, y, dy/dt, d^2y/dt^2) = 0 for second-order time integrators (PETSc TSALPHA2).

    accelerations: placeholders for d^2y/dt^2 in ``residual`` (same spaces as ``fields``).
    time_orders:   per block 2 (its accelerations enter), 1 (only its rate; the
                   accelerations entry is None) or 0 (algebraic: neither enters); empty:
                   all 2.
    lie_group:     the fields include rotation increments reset by after_step (a rod
                   with rotation vectors): generalized-alpha on the rotation group
                   (integrators/lie_alpha.py) advances it, not PETSc TS; without a
                   second-order block those increments are algebraic (a quasi-static
                   rod), and TimeStepper's per-step schemes advance it too.
    error_scales:  per block the size its local time error is measured against (error
                   control, lie_alpha.LocalError: atol times it): a length for
                   displacements, 1 (rad) for angles; empty: the mesh's extent for each.
    scale_motions: fraction -> None: the prescribed motions' values scaled by the
                   fraction from then on (1: as prescribed), which the consistent start
                   follows in committed parts (integrators/lie_alpha.py: a rod's end
                   turned beyond a quarter turn at t0); None: sub-solves of the
                   Dirichlet values.
    motion_turn:   t -> the largest angle (rad) by which the prescribed motions turn an
                   end at t (the number of the consistent start's parts grows with it).
    starting_accelerations: how the integrator starts the second-order blocks:
                   "balance" (solved from the residual at t0) or "zero" (the state given
                   is at rest: zero accelerations; STARTING_ACCELERATIONS).
    friction_lookahead: a Constant tau (0) in the residual, or None: friction reads the
                   velocity v + tau a there.  The regularised friction law exerts no force
                   at zero slip, so the accelerations solved at t0 from a state at rest
                   would be frictionless; the rotation-group integrator sets tau to the
                   first step while it solves them (friction then reads the slip that
                   the first step would make: a rod held by friction starts held, one
                   sliding starts at Coulomb's force), and back to 0.
    rest_in_contact: solve -> None, called after the starting accelerations are solved:
                   moves what starts at rest within a contact barrier to where the barrier
                   carries it (a rod's ObstacleContact.rest_on_barriers), calling
                   ``solve()`` (the integrator's: the accelerations solved again at the
                   moved state) after each move; None: nothing to move.
    """

    accelerations: list[fem.Function] = field(default_factory=list)
    time_orders: list[int] = field(default_factory=list)
    lie_group: bool = False
    error_scales: list[float] = field(default_factory=list)
    scale_motions: Callable[[float], None] | None = None
    motion_turn: Callable[[float], float] | None = None
    starting_accelerations: str = "balance"
    friction_lookahead: fem.Constant | None = None
    rest_in_contact: Callable[[Callable[[], None]], None] | None = None

    def __post_init__(self):
        super().__post_init__()
        one_of("starting_accelerations", self.starting_accelerations, STARTING_ACCELERATIONS)
        for name in ("accelerations", "time_orders", "error_scales"):
            given = getattr(self, name)
            if given and len(given) != len(self.fields):
                raise ValueError(f"{name}: one entry per field ({len(self.fields)}), got "
                                 f"{len(given)}")

    def configuration_norm(self) -> float:
        """Rotation increments (lie_group) and displacements are 0 at rest: the norm of a
        state with every dof of its block's error scale, sqrt(sum_i dofs_i scale_i^2)
        (the mesh's extent where no scales are given), over all ranks."""
        if not self.lie_group:
            return 0.0
        return float(np.sqrt(sum(f.function_space.dofmap.index_map.size_global
                                 * f.function_space.dofmap.index_map_bs * scale ** 2
                                 for f, scale in zip(self.fields, self.block_scales()))))

    def block_scales(self) -> list[float]:
        """Per block its size: ``error_scales``, else the mesh's extent along x."""
        if self.error_scales:
            return list(self.error_scales)
        mesh = self.fields[0].function_space.mesh
        x, comm = mesh.geometry.x[:, 0], mesh.comm
        extent = comm.allreduce(x.max(), op=MPI.MAX) - comm.allreduce(x.min(), op=MPI.MIN)
        return [extent] * len(self.fields)

    @property
    def per_step_schemes(self) -> bool:
        """TimeStepper's per-step schemes apply: no block is of second order (the
        rotation increments of a quasi-static rod are algebraic: their rate enters
        nowhere, and a stage state a theta is a rotation between q_n and q_n c(theta))."""
        return 2 not in (self.time_orders or [2])

