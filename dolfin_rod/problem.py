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


@dataclass
class TimeDependentValue:
    """A fem.Constant in the residual whose value is a function of time (a load)."""

    constant: fem.Constant
    history: Callable[[float], float | np.ndarray]

    def at(self, t: float) -> np.ndarray:
        return np.asarray(self.history(t), dtype=float).reshape(self.constant.value.shape)


@dataclass
class SemiDiscreteProblem:
    """F(t, y, dy/dt; v) = 0 on a blocked (ufl.MixedFunctionSpace-like) space.

    fields:    y, one Function per block: the unknowns, updated in place by integrators.
    rates:     placeholders for dy/dt in ``residual`` (same spaces as ``fields``).
    residual:  one UFL form per block, linear in the block's test function.
    loads:     constants in ``residual`` set from their histories at each evaluation time.
    bcs:       Dirichlet conditions on the blocks of ``fields``.
    set_bcs:   sets the prescribed values of ``bcs`` (and their rates) at time t.
    """

    fields: list[fem.Function]
    rates: list[fem.Function]
    residual: list[ufl.Form]
    loads: list[TimeDependentValue] = field(default_factory=list)
    bcs: list[fem.DirichletBC] = field(default_factory=list)
    set_bcs: Callable[[float], None] = lambda t: None

    def __post_init__(self):
        if not (len(self.fields) == len(self.rates) == len(self.residual)):
            raise ValueError("fields, rates and residual must have one entry per block")

    @property
    def comm(self):
        return self.fields[0].function_space.mesh.comm

    def set_loads(self, t: float) -> None:
        for load in self.loads:
            load.constant.value[...] = load.at(t)


@dataclass
class SecondOrderProblem(SemiDiscreteProblem):
    """F(t, y, dy/dt, d^2y/dt^2) = 0 for second-order time integrators (PETSc TSALPHA2).

    accelerations: placeholders for d^2y/dt^2 in ``residual`` (same spaces as ``fields``).
    after_step:    called with the accepted state in fields/rates, to update what the
                   model derives from them (e.g. the velocity fields of its first-order
                   form, which its diagnostics read).
    time_orders:   per block 2 (its accelerations enter) or 1 (only its rate; the
                   accelerations entry is None); empty: all 2.
    check_step:    called when a step's Newton has converged (its state in fields): a
                   reason to reject the step (it is then redone smaller), or None; e.g.
                   a rotation increment no resolved step makes (a spurious root).
    lie_group:     the fields include rotation increments reset by after_step (a rod
                   with rotation vectors): only generalized-alpha on the rotation group
                   (integrators/lie_alpha.py) advances it, not PETSc TS.
    error_scales:  per block the size its local time error is measured against (error
                   control, lie_alpha.LocalError: atol times it): a length for
                   displacements, 1 (rad) for angles; empty: the mesh's extent for each.
    """

    accelerations: list[fem.Function] = field(default_factory=list)
    after_step: Callable[[], None] = lambda: None
    check_step: Callable[[], str | None] = lambda: None
    time_orders: list[int] = field(default_factory=list)
    lie_group: bool = False
    error_scales: list[float] = field(default_factory=list)

    def __post_init__(self):
        super().__post_init__()
        for name in ("accelerations", "time_orders", "error_scales"):
            given = getattr(self, name)
            if given and len(given) != len(self.fields):
                raise ValueError(f"{name}: one entry per field ({len(self.fields)}), got "
                                 f"{len(given)}")
