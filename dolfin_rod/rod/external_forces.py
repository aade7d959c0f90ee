"""Loads on the rod (PyElastica's ``external_forces``): end, distributed and point forces
and couples, dead or follower, with their histories, and linear drag f = -c dr/dt.

Their virtual work enters the balance blocks (balance.force_work, balance.couple_work);
the same densities tested with the velocities (V, W) give the power of the loads.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import dolfinx.fem as fem
import numpy as np
import ufl

from ..theory import balance
from ..theory.rotations import rotation_matrix
from ..checks import end_name
from ..fem.fe_model import ENDS
from ..fem.problem import TimeDependentValue
from .discretisation import Discretisation, Unknowns
from .material import DAMPING, is_zero


@dataclass
class EndLoad:
    """A force or couple at an end: value(3,) * history(t); dead (spatial components)
    or follower (material components, i.e. rotating with the end section)."""

    kind: str                        # "force" or "couple"
    value: Sequence[float]
    history: Callable = field(default=lambda t: 1.0)
    end: str = "end"                 # "start" (s = 0) or "end" (s = L), as the scene's
    follower: bool = False           # loads.start_force, end_couple, ...

    def __post_init__(self):
        self.end = end_name("EndLoad", self.end, stacklevel=3)    # the caller's line


@dataclass
class DistributedLoad:
    """A force or couple per unit reference length: value(s) * history(t)."""

    kind: str                        # "force" or "couple"
    value: Sequence[float] | Callable
    history: Callable = field(default=lambda t: 1.0)
    follower: bool = False


@dataclass
class PointLoad:
    """A concentrated force or couple at the rod's own arc length s (0 <= s <= L):
    value(3,) * history(t), dead or follower (as EndLoad)."""

    kind: str                        # "force" or "couple"
    value: Sequence[float]
    s: float
    history: Callable = field(default=lambda t: 1.0)
    follower: bool = False


def check_loads(end_loads, distributed_loads, point_loads=(), length: float = np.inf) -> None:
    for load in point_loads:
        if not (np.isfinite(load.s) and 0.0 <= load.s <= length):
            raise ValueError(f"PointLoad s must be on the rod, 0 <= s <= L = {length:g}, "
                             f"got {load.s!r}")
    for load in list(end_loads) + list(distributed_loads) + list(point_loads):
        if load.kind not in ("force", "couple"):
            raise ValueError(f"load kind must be 'force' or 'couple', got {load.kind!r}")
        if not callable(load.value) and np.shape(load.value) != (3,):
            raise ValueError(f"load value must be a 3-vector, got {load.value!r}")
        if not callable(load.value) and not np.all(np.isfinite(np.asarray(load.value,
                                                                          float))):
            raise ValueError(f"{type(load).__name__} value must be finite, got "
                             f"{list(load.value)!r}")
        if not np.isfinite(float(load.history(0.0))):
            raise ValueError(f"{type(load).__name__} history must be finite, got "
                             f"{load.history(0.0)!r} at t = 0")
    for load in end_loads:
        if load.end not in ENDS:
            raise ValueError(f"EndLoad end must be 'start' (s = 0) or 'end' (s = L), got "
                             f"{load.end!r}")


def _load_value(load, rod: int, disc: Discretisation):
    """The load's vector (a constant, or value(s) for a distributed profile, s the rod's
    own arc length)."""
    if callable(load.value):
        return ufl.as_vector(list(load.value(disc.pieces.local_s(rod))))
    return fem.Constant(disc.mesh, np.asarray(load.value, float))


def point_weight(load: PointLoad, rod: int, disc: Discretisation):
    """The density that puts a point load at s_0 on the nodes when integrated by
    ``point_measure``: the P1 hat functions' values N_i(s_0) (the consistent load vector,
    exact for P1 test functions; at a node, all of it on that node)."""
    layout = disc.pieces.layout
    # Constants, not numbers: the compiled kernels are shared by models of other s, h
    h = fem.Constant(disc.mesh, layout.lengths[rod] / layout.n_cells[rod])
    distance = abs(disc.pieces.local_s(rod, offset=False)
                   - fem.Constant(disc.mesh, float(load.s)))
    return ufl.max_value(0.0, 1.0 - distance / h) / h, h


def point_measure(density, h, disc: Discretisation):
    """density integrated by the vertex rule (h/2 per cell at each node) plus h/2 at the
    end points: every node's value times h."""
    return density * disc.dx_v + (h / 2) * density * disc.ds


def apply_loads(F: dict, unk: Unknowns, disc: Discretisation, end_loads, distributed_loads,
                point_loads=()):
    """Subtracts each load's virtual work from its balance block; returns the load
    histories (TimeDependentValue) and the power of the loads (a UFL form, or 0).
    end_loads, distributed_loads, point_loads: (rod index, load) pairs (layout.py: a
    load acts on its rod only)."""
    q, dTheta = unk.q, unk.dTheta
    histories, power = [], 0
    chi = disc.pieces.indicator
    placed = [(k, load, disc.end_weight[load.end] * chi(k), lambda f: f * disc.ds)
              for k, load in end_loads]
    placed += [(k, load, chi(k), lambda f: f * disc.dx) for k, load in distributed_loads]
    for k, load in point_loads:
        density, h = point_weight(load, k, disc)
        placed.append((k, load, chi(k) * density,
                       lambda f, h=h: point_measure(f, h, disc)))
    for rod, load, weight, integral in placed:
        amp = fem.Constant(disc.mesh, 0.0)
        histories.append(TimeDependentValue(amp, load.history))
        val = weight * amp * _load_value(load, rod, disc)
        if load.kind == "force":
            F["displacement"] -= integral(balance.force_work(
                val, q, unk.t["displacement"], load.follower))
            power += integral(balance.force_work(val, q, unk.V, load.follower))
        else:
            F[unk.rotation] -= integral(balance.couple_work(val, q, dTheta, load.follower))
            power += integral(balance.couple_work(val, q, unk.W, load.follower))
    return histories, power


def drag(F: dict, unk: Unknowns, c: dict, params: list, disc: Discretisation):
    """Linear drag f = -c V in the displacement block and rotational damping, the couple
    per length -C W (material: ``rotational_drag``) or -C_s w (spatial, w = R W:
    ``spatial_rotational_drag``, i.e. C = R^T C_s R) in the rotation block; returns
    their dissipation c V.V + W.C W integrated (0 without any on every rod)."""
    dissipation = []
    if not all(is_zero(p.drag) for p in params):
        F["displacement"] += c["drag"] * ufl.inner(unk.V, unk.t["displacement"]) * disc.dx
        dissipation.append(c["drag"] * ufl.inner(unk.V, unk.V) * disc.dx)
    for name in DAMPING:
        if name in c:
            C = c[name]
            if name.startswith("spatial"):
                R = rotation_matrix(unk.q)
                C = ufl.dot(ufl.transpose(R), ufl.dot(C, R))
            F[unk.rotation] += ufl.inner(ufl.dot(C, unk.W), unk.dTheta) * disc.dx
            dissipation.append(ufl.inner(unk.W, ufl.dot(C, unk.W)) * disc.dx)
    return sum(dissipation[1:], dissipation[0]) if dissipation else 0
