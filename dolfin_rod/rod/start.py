"""The rod's starting state, apart from its stress-free shape: where the rod starts and
which way it points, its starting centre line (a curve, possibly stretched), velocities,
and a start in static equilibrium.

The stress-free shape stays that of the reference strains (``RodParameters``:
straight, or the helix/circle of constant ``reference_curvature``; rod/placement.py);
a starting curve only moves the rod, so a bent start of a straight rod is stressed:

    StartingState(shape=Arc(radius=0.5))               # a straight rod bent into an arc
    StartingState(shape=Straight(stretch=1.01))        # pre-stretched by 1 %
    StartingState(shape=Polyline(points, rest_arc_length=s_points))   # any centre line
    StartingState(position=p, orientation=theta)       # the stress-free shape, placed

Every curve is given in the frame of the rod's start: it starts at the origin with the
directors (d1, d2, d3) = (e1, e2, e3), d3 the tangent (a polyline: along its first
segment, d1 from ``normal``), and is then placed rigidly, r = p + Q r_curve,
R = Q R_curve, with p = ``position`` and Q the rotation of the rotation vector
``orientation``.  Lengths are rest arc lengths s in [0, L]; a curve's ``stretch``
|r_s| (a polyline: its ``rest_arc_length`` per point) pre-stretches the start.

Velocities (dynamic rods): the spatial velocity v(s) and angular velocity w(s), each a
3-vector or a callable of the rest arc length s (a numpy array of n points) returning
(n, 3); with ``rotation_centre`` c the velocity gets the rigid part w x (r - c).  At a
supported end the support's motion overrides them.  ``equilibrium``: before the
dynamics, the positions and rotations are solved for static equilibrium with the
loads at t = 0 (natural strains kept), from the starting shape (quasi-static
pre-loading); a rod with a clamped end or a prescribed end rotation only (with pinned
or free ends alone the sections turn about their tangents for free).

``acceleration`` (dynamic rods with rotation vectors, advanced by generalized-alpha,
which starts from the accelerations at t = 0): "balance" (the default) solves them from
the balance laws at t = 0, friction read at the slip velocity v + h a that the first
step h would reach (the regularised law exerts no force at rest: read at rest, a rod
held by friction would start frictionless); "zero" starts them at 0, for a state known
to be at rest although its discrete balance is not exactly met (a rope laid over others
at rest: its start's imbalance is not carried into the first steps' velocities).
"""


from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..checks import EQUILIBRIUM_NEEDS, STARTING_ACCELERATIONS, one_of, polyline_problem
from ..theory.quaternions import (np_qmul, np_quaternion_from_matrix,
                                  np_quaternion_from_rotation_vector, np_rotation_matrix)
from .placement import helix, place, shape as stress_free_shape

Field = tuple | Callable


@dataclass(frozen=True)
class Straight:
    """A straight start along d3, stretched by ``stretch``: r = stretch s e3."""

    stretch: float = 1.0

    def frames(self, s, length: float, n_cells: int):
        return constant_strain_curve(s, (0.0, 0.0, 0.0), self.stretch)


@dataclass(frozen=True)
class Arc:
    """A circular arc of ``radius`` in the (d1, d3) plane of the start, bending towards
    d1 (curvature 1/radius about d2), stretched by ``stretch``."""

    radius: float
    stretch: float = 1.0

    def frames(self, s, length: float, n_cells: int):
        return constant_strain_curve(s, (0.0, self.stretch / self.radius, 0.0), self.stretch)


@dataclass(frozen=True)
class Helix:
    """A helix of ``radius`` and ``pitch`` (rise per turn; < 0: left-handed), stretched by
    ``stretch``; d1 the principal normal, d2 the binormal.  Its curvature and torsion
    kappa = a/(a^2 + c^2), tau = c/(a^2 + c^2) (a the radius, c = pitch/(2 pi)) are the
    material strains u = (0, kappa, tau) per unit length of the curve; its axis is
    (0, a, c)/sqrt(a^2 + c^2) in the start's frame."""

    radius: float
    pitch: float
    stretch: float = 1.0

    def frames(self, s, length: float, n_cells: int):
        a, c = self.radius, self.pitch / (2 * np.pi)
        u = np.array([0.0, a, c]) / (a * a + c * c)
        return constant_strain_curve(s, tuple(self.stretch * u), self.stretch)


@dataclass(frozen=True)
class Polyline:
    """A centre line through ``points`` (N x 3, in the start's frame as above; the
    first at the origin for a start at ``position``).  ``rest_arc_length`` (N numbers
    from 0 to L): the rest arc length of each point, so that the start is stretched by
    the ratio of each segment's length to its rest length; without it the polyline's
    own arc length, which must then be the rod's length.  The rod's nodes are the
    points of the polyline at the nodes' rest arc lengths (linear in between); d3 at a
    node is the mean of the unit tangents of its two mesh segments (an O(h^2) shear
    where the polyline bends) and d1 is ``normal`` made perpendicular to d3 at s = 0,
    then carried from node to node by the smallest rotation between their tangents
    (parallel transport: an untwisted start)."""

    points: tuple
    rest_arc_length: tuple | None = None
    normal: tuple = (1.0, 0.0, 0.0)

    def arc_lengths(self) -> np.ndarray:
        """The rest arc length of each point."""
        if self.rest_arc_length is not None:
            return np.asarray(self.rest_arc_length, float)
        chords = np.linalg.norm(np.diff(np.asarray(self.points, float), axis=0), axis=1)
        return np.concatenate(([0.0], np.cumsum(chords)))

    def frames(self, s, length: float, n_cells: int):
        grid = np.linspace(0.0, length, n_cells + 1)
        points, arc = np.asarray(self.points, float), self.arc_lengths()
        nodes = np.stack([np.interp(grid, arc, points[:, i]) for i in range(3)], axis=1)
        chords = np.diff(nodes, axis=0)
        chords /= np.linalg.norm(chords, axis=1)[:, None]
        tangents = np.concatenate((chords[:1], chords[:-1] + chords[1:], chords[-1:]))
        tangents /= np.linalg.norm(tangents, axis=1)[:, None]
        d1 = parallel_transport(tangents, np.asarray(self.normal, float))
        R = np.stack([d1, np.cross(tangents, d1), tangents], axis=-1)
        index = np.rint(np.asarray(s) * n_cells / length).astype(int)
        return nodes[index], continuous(np_quaternion_from_matrix(R))[index]


def curve(table: dict | None):
    """The curve (Straight, Arc, Helix, Polyline) of a scene's shape table
    (scenes/values.starting_shape), None for None."""
    if table is None:
        return None
    keys = dict(table)
    kind = keys.pop("type")
    return {"straight": Straight, "arc": Arc, "helix": Helix, "polyline": Polyline}[kind](**keys)


def continuous(q: np.ndarray) -> np.ndarray:
    """Unit quaternions of nodes in order along the rod, signs chosen so that neighbours
    lie in one hemisphere (q_k . q_k+1 > 0): the P1 interpolant of q and -q passes
    through 0 (a polyline turning by pi gave nodes with q . q = -1: infinite strains)."""
    flips = np.sign(np.einsum("ij,ij->i", q[1:], q[:-1]))
    return q * np.concatenate(([1.0], np.cumprod(np.where(flips == 0, 1.0, flips))))[:, None]


def parallel_transport(tangents: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Unit d1 perpendicular to each tangent: ``normal`` made perpendicular to the first,
    then turned from one tangent to the next by the smallest rotation between them."""
    d1 = np.empty_like(tangents)
    d = normal - (normal @ tangents[0]) * tangents[0]
    d1[0] = d / np.linalg.norm(d)
    for i in range(1, len(tangents)):
        a, b = tangents[i - 1], tangents[i]
        axis, cos = np.cross(a, b), a @ b
        # Rodrigues for the rotation taking a to b: d cos + (k x d) + k (k.d)/(1 + cos)
        d = d1[i - 1]
        d1[i] = d * cos + np.cross(axis, d) + axis * (axis @ d) / (1 + cos)
    return d1


def constant_strain_curve(s, u0, stretch: float):
    """Centre line and unit quaternions of the curve of constant material strains u0,
    v0 = stretch e3 from the origin with R(0) = I (placement.helix)."""
    return helix(np.asarray(s, float), u0, (0.0, 0.0, stretch))


@dataclass(frozen=True)
class StartingState:
    """The rod at t = 0 (module docstring).  ``shape`` None: the stress-free shape."""

    shape: Straight | Arc | Helix | Polyline | None = None
    position: tuple = (0.0, 0.0, 0.0)
    orientation: tuple = (0.0, 0.0, 0.0)
    velocity: Field = (0.0, 0.0, 0.0)
    angular_velocity: Field = (0.0, 0.0, 0.0)
    rotation_centre: tuple | None = None
    equilibrium: bool = False
    acceleration: str = "balance"

    @property
    def moving(self) -> bool:
        """Velocities given (not the default zero)."""
        return any(callable(f) or any(f) for f in (self.velocity, self.angular_velocity))

    def frames(self, s, stress_free: Callable, length: float, n_cells: int):
        """(r, q) at the rest arc lengths s: the shape (``stress_free(s)`` if None),
        placed at ``position`` with ``orientation``."""
        r, q = (stress_free(s) if self.shape is None
                else self.shape.frames(s, length, n_cells))
        qQ = np_quaternion_from_rotation_vector(np.asarray(self.orientation, float))
        return (np.asarray(self.position, float) + r @ np_rotation_matrix(qQ).T,
                np_qmul(qQ, q))

    def velocities(self, s, r) -> tuple[np.ndarray, np.ndarray]:
        """(v, w) at the points s with positions r: spatial velocity and angular
        velocity, (n, 3) each."""
        w = _field(self.angular_velocity, s)
        v = _field(self.velocity, s)
        if self.rotation_centre is not None:
            v = v + np.cross(w, r - np.asarray(self.rotation_centre, float))
        return v, w


class RodStarts:
    """The starting states of rods of a system, by rod name (RodSystem.set_initial_state(
    start={name: StartingState})): each curve, position and orientation in its rod's
    placed frame (Rod.position, Rod.orientation: by default the rod starts where it is
    placed), velocities spatial; the other rods start in their stress-free shapes at
    rest.  The interface of a StartingState over the system's mesh (``layout``), and
    ``rod_state`` of one rod (joints.check_joints_at_start)."""

    def __init__(self, starts: dict, rods, layout=None):
        self.starts, self.rods, self.layout = dict(starts), list(rods), layout
        self.moving = any(start.moving for start in self.starts.values())
        self.equilibrium = any(start.equilibrium for start in self.starts.values())
        # one way for the system (check_rod_starts refuses starts that differ)
        self.acceleration = ("zero" if any(start.acceleration == "zero"
                                           for start in self.starts.values()) else "balance")

    def rod_state(self, rod, own) -> tuple[np.ndarray, ...]:
        """(r, q, v, w) of ``rod`` (rods.Rod) at its own nodes' arc lengths ``own``."""
        own = np.asarray(own, float)
        start = self.starts.get(rod.name, StartingState())
        r, q = place(rod, *start.frames(
            own, lambda x: stress_free_shape(rod.params, x, rod.n_cells), rod.params.length,
            rod.n_cells))
        return (r, q, *start.velocities(own, r))

    def _pieces(self, s):
        """(mask of s on a started rod, its state there) for each started rod."""
        rod_of = self.layout.rod_of(s)
        for k, rod in enumerate(self.rods):
            if rod.name in self.starts:
                on = rod_of == k
                yield on, self.rod_state(rod, s[on] - self.layout.starts[k])

    def frames(self, s, stress_free: Callable, length: float, n_cells: int):
        s = np.asarray(s, float)
        r, q = stress_free(s)
        for on, (r_on, q_on, _, _) in self._pieces(s):
            r[on], q[on] = r_on, q_on
        return r, q

    def velocities(self, s, r) -> tuple[np.ndarray, np.ndarray]:
        s = np.asarray(s, float)
        v, w = np.zeros((len(s), 3)), np.zeros((len(s), 3))
        for on, (_, _, v_on, w_on) in self._pieces(s):
            v[on], w[on] = v_on, w_on
        return v, w


def check_rod_starts(starts: dict, rods, dynamic: bool, supported: bool) -> None:
    """check_start of each rod's start, a ValueError naming ``start['<rod>']``."""
    names = [rod.name for rod in rods]
    if not isinstance(starts, dict) or any(name not in names for name in starts):
        raise ValueError(f"start: a system's starting states are {{rod name: StartingState}}"
                         f" of its rods {names}, got {starts!r}")
    for rod in rods:
        try:
            check_start(starts.get(rod.name), rod.params.length, dynamic, supported)
        except ValueError as err:
            raise ValueError(f"start[{rod.name!r}]" + str(err).removeprefix("start")) from err
    asked = {name: start.acceleration for name, start in starts.items()}
    if len(set(asked.values())) > 1:
        name = next(n for n, a in asked.items() if a != next(iter(asked.values())))
        raise ValueError(f"start[{name!r}].acceleration: the rods of a system start their "
                         f"accelerations one way (one integrator), got {asked}")


def _field(value: Field, s) -> np.ndarray:
    if callable(value):
        return np.asarray(value(np.asarray(s, float)), float).reshape(len(s), 3)
    return np.tile(np.asarray(value, float), (len(s), 1))


def check_start(start: StartingState | None, length: float, dynamic: bool,
                supported: bool) -> None:
    """ValueError naming the parameter (start.<field>) for a starting state that does not
    fit the rod (``supported``: a clamped end, a prescribed end rotation or obstacles to
    rest on: the static problem of ``equilibrium`` is not singular)."""
    if start is None:
        return
    if start.equilibrium and not supported:
        raise ValueError(f"start.equilibrium: {EQUILIBRIUM_NEEDS}")
    one_of("start.acceleration", start.acceleration, STARTING_ACCELERATIONS)
    for name in ("position", "orientation"):
        _vector(f"start.{name}", getattr(start, name))
    if start.rotation_centre is not None:
        _vector("start.rotation_centre", start.rotation_centre)
    if not dynamic and (start.moving or start.acceleration == "zero"):
        name = "velocity" if start.moving else "acceleration"
        raise ValueError(f"start.{name}: the rod is quasi-static (density = 0): it has no "
                         "velocities and is in equilibrium at every step")
    problem = shape_problem(start.shape, length)
    if problem:
        raise ValueError(f"start.shape{problem[0]}: {problem[1]}")


def shape_problem(shape, length: float) -> tuple[str, str] | None:
    """(".<field>" or "", reason) for a curve (Straight, Arc, Helix, Polyline or None)
    that is wrong or does not fit a rod of ``length``; else None."""
    if shape is not None and not isinstance(shape, (Straight, Arc, Helix, Polyline)):
        return "", f"must be a Straight, Arc, Helix or Polyline, got {shape!r}"
    if isinstance(shape, (Straight, Arc, Helix)) and not shape.stretch > 0:
        return ".stretch", f"must be > 0, got {shape.stretch}"
    if isinstance(shape, Arc) and not shape.radius > 0:
        return ".radius", f"must be > 0, got {shape.radius}"
    if isinstance(shape, Helix) and not (shape.radius > 0 and np.isfinite(shape.pitch)):
        return "", (f"a helix needs radius > 0 and a finite pitch, got radius "
                    f"{shape.radius}, pitch {shape.pitch}")
    if isinstance(shape, Polyline):
        problem = polyline_problem(shape.points, shape.rest_arc_length, shape.normal, length)
        if problem:
            return f".{problem[0]}", problem[1]
    return None


def _vector(name: str, value) -> np.ndarray:
    v = np.asarray(value, float)
    if v.shape != (3,) or not np.isfinite(v).all():
        raise ValueError(f"{name}: a finite 3-vector, got {value!r}")
    return v
