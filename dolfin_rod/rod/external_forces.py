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


@dataclass
class LoadData:
    """A load's Constants (load_data): its amplitude, its value (None: a profile value(s),
    made with the terms) and, at a point, the cell size h and the point s_0."""

    rod: int
    load: object
    where: str                # "end", "distributed" or "point"
    amplitude: fem.Constant
    value: fem.Constant | None
    point: tuple = ()         # (h, s_0) of a point load

    def constants(self) -> dict:
        named = {"amplitude": self.amplitude, "value": self.value,
                 **dict(zip(("h", "s0"), self.point))}
        return {name: const for name, const in named.items() if const is not None}


def _load_value(data: LoadData, disc: Discretisation):
    """The load's vector (its Constant, or value(s) for a distributed profile, s the rod's
    own arc length)."""
    if data.value is None:
        return ufl.as_vector(list(data.load.value(disc.pieces.local_s(data.rod))))
    return data.value


def point_weight(data: LoadData, disc: Discretisation):
    """The density that puts a point load at s_0 on the nodes when integrated by
    ``point_measure``: the P1 hat functions' values N_i(s_0) (the consistent load vector,
    exact for P1 test functions; at a node, all of it on that node)."""
    h, s0 = data.point
    distance = abs(disc.pieces.local_s(data.rod, offset=False) - s0)
    return ufl.max_value(0.0, 1.0 - distance / h) / h


def point_measure(density, h, disc: Discretisation):
    """density integrated by the vertex rule (h/2 per cell at each node) plus h/2 at the
    end points: every node's value times h."""
    return density * disc.dx_v + (h / 2) * density * disc.ds


def load_data(disc: Discretisation, end_loads, distributed_loads, point_loads=()):
    """The loads' Constants, made before their terms (apply_loads): the load histories
    (TimeDependentValue) and each load's LoadData.  end_loads, distributed_loads,
    point_loads: (rod index, load) pairs (layout.py: a load acts on its rod only)."""
    layout = disc.pieces.layout
    placed = [(k, load, "end", ()) for k, load in end_loads]
    placed += [(k, load, "distributed", ()) for k, load in distributed_loads]
    # Constants, not numbers: the compiled kernels are shared by models of other s, h
    placed += [(k, load, "point", (fem.Constant(disc.mesh, layout.lengths[k] / layout.n_cells[k]),
                                   fem.Constant(disc.mesh, float(load.s))))
               for k, load in point_loads]
    histories, data = [], []
    for rod, load, where, point in placed:
        amp = fem.Constant(disc.mesh, 0.0)
        histories.append(TimeDependentValue(amp, load.history))
        value = None if callable(load.value) else fem.Constant(
            disc.mesh, np.asarray(load.value, float))
        data.append(LoadData(rod, load, where, amp, value, point))
    return histories, data


def apply_loads(F: dict, unk: Unknowns, disc: Discretisation, loads: list[LoadData]):
    """Subtracts each load's virtual work from its balance block (``loads``: load_data);
    returns the power of the loads (a UFL form, or 0)."""
    q, dTheta = unk.q, unk.dTheta
    power = 0
    chi = disc.pieces.indicator
    placed = []
    for data in loads:
        if data.where == "end":
            placed.append((data, disc.end_weight[data.load.end] * chi(data.rod),
                           lambda f: f * disc.ds))
        elif data.where == "distributed":
            placed.append((data, chi(data.rod), lambda f: f * disc.dx))
        else:
            placed.append((data, chi(data.rod) * point_weight(data, disc),
                           lambda f, h=data.point[0]: point_measure(f, h, disc)))
    for data, weight, integral in placed:
        load = data.load
        val = weight * data.amplitude * _load_value(data, disc)
        if load.kind == "force":
            F["displacement"] -= integral(balance.force_work(
                val, q, unk.t["displacement"], load.follower))
            power += integral(balance.force_work(val, q, unk.V, load.follower))
        else:
            F[unk.rotation] -= integral(balance.couple_work(val, q, dTheta, load.follower))
            power += integral(balance.couple_work(val, q, unk.W, load.follower))
    return power


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
