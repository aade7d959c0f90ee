"""Contact of the rod with rigid obstacles (issue 26; docs/contact.md): planes
(half-spaces), spheres, finite cylinders and triangle meshes (triangle_mesh.py) touching
the rod's centre line thickened by its radius r, with a smooth barrier of stated gap
delta and Coulomb friction.

Gap of a centre-line point p to obstacle k: g_k(p) = d_k(p) - r, d_k the signed distance
of p to the obstacle's surface (negative inside).  Contact law (per unit length, at the
nodes: the trapezoidal rule, so every node carries its own contact force):

    energy     kappa b(g),   b(g) = -(g - delta)^2 ln(g / delta)   for 0 < g < delta,
               b = 0 for g >= delta (C^2 there), and below g_min = XI_MIN delta its
               second-order Taylor polynomial at g_min (finite for Newton's iterates;
               an accepted state never has g <= 0: ``check_step`` rejects the step);
    friction   f_t = -mu lambda phi(|v_t| / eps) v_t / |v_t|,  phi(y) = 3y/2 - y^3/2 for
               y < 1, 1 beyond (C^1), with the normal force lambda = -kappa b'(g) of the
               last accepted state (lagged, as in incremental potential contact), v_t the
               velocity tangent to the obstacle of the contact point on the rod's surface,
               c = -r n from the centre line (n the obstacle's outward normal): v_t the
               tangential part of v + W_3 d_3 x c (W_3 = W . e_3 the spin about the rod's
               axis d_3), and eps the slip tolerance: a rod held by static friction creeps
               at less than eps.  f_t acts at that point: on the centre line the force
               f_t and the torque (c x f_t) . d_3 about the axis (a rod across a slope
               rolls; twisting a rod on a floor meets friction).  The sections' tilt
               rates (W_1, W_2: bending and shear) are left out of the point's velocity,
               and the bending couple out of the couple (docs/contact.md, "Rolling").

The normal force enters the residual as the derivative of the contact energy (its
Jacobian by UFL: consistent), the friction force and torque as the virtual work
f_t . dx + ((c x f_t) . d_3) dTheta_3 (their Jacobian by UFL too, through the
integrator's rates); the contact energy joins K + Psi in the power balance, the
friction's power -f_t . (v + W_3 d_3 x c) >= 0 the dissipation.
"""

from __future__ import annotations

import functools
import math
import warnings
from dataclasses import dataclass
from typing import Sequence

import dolfinx.fem as fem
import numpy as np
import ufl
from ufl.algorithms import extract_arguments, extract_coefficients
from mpi4py import MPI

from ..fem import compat
from ..checks import nonnegative, positive, sample_points
from ..theory.rotations import rotation_matrix
from . import segments
from .triangle_mesh import FACE, MeshError, Surface, placed_surface

SHAPES = ("plane", "sphere", "cylinder", "mesh")
CONTACT_MODES = ("auto", "nodes", "segments")   # where an obstacle's barrier acts
SEGMENT_SHAPES = ("sphere", "cylinder", "mesh")  # ... on segments (a mesh: its sharp
                                                 # edges): obstacle_segments.py
XI_MIN = 1e-4             # g_min / delta: the barrier's exact range is [g_min, delta]
BARRIER_CURVATURE = 2 * math.log(2) + 5.0   # b''(delta / 2) (dimensionless)
SWEEP_DEPTH = 48          # halvings of a segment's sweep in a step (sweep_entry)


class InitialOverlap(ValueError):
    """The rod's initial state meets an obstacle (``obstacle``: its index)."""

    def __init__(self, reason: str, obstacle: int):
        super().__init__(reason)
        self.obstacle = obstacle

    @classmethod
    def at(cls, where: str, s: float, g: float, k: int, gap: float,
           shape: str) -> "InitialOverlap":
        """The overlap of ``where`` ("centre line", "segment") at s, gap g <= 0 to
        obstacles[k] of ``shape``, with where the rod may start instead: a rod just
        touching (|g| at most a millionth of the gap: round-off of a rod laid on a floor
        at its radius) starts where the barrier is infinite; a rod behind a mesh may see
        its triangles turned the wrong way (an open bowl given clockwise from inside)."""
        place = (f"start it off the surface by a gap in (0, {gap:.3g}] (contact.gap; "
                 "the barrier holds the rod there) or farther")
        if shape == "mesh":
            place += (f"; if the rod is on the side it should stay on, the triangles of "
                      f"obstacles[{k}] face the other way: give them counter-clockwise "
                      f"seen from the rod's side")
        if -g <= 1e-6 * gap:
            return cls(f"the rod's {where} at s = {s:.4g} touches obstacles[{k}] at t = 0 "
                       f"(gap 0 between the surfaces, where the barrier is infinite): "
                       f"{place}", k)
        return cls(f"the rod's {where} at s = {s:.4g} is {-g:.3g} closer to obstacles[{k}] "
                   f"than the rod's radius at t = 0 (it cuts into the obstacle): move the "
                   f"obstacle or the rod; {place}", k)


@dataclass
class Obstacle:
    """A rigid obstacle, in the keys of a scene's [[obstacles]]: ``shape`` "plane" (the
    half-space behind ``point`` against the outward ``normal``), "sphere" (``radius``
    around ``centre``) or "cylinder" (``radius``, ``length`` along ``axis`` through its
    ``centre``) or "mesh" (a triangle surface: ``file``, an STL or OBJ file, or
    ``vertices`` and ``triangles``, placed by x = centre + R(rotation) scale v, rotation a
    rotation vector; triangle_mesh.py); ``friction`` the Coulomb coefficient mu >= 0;
    ``contact`` where its barrier acts: "nodes" (this module), "segments" (a sphere's or
    cylinder's; a mesh's nodes and its sharp edges' segments: obstacle_segments.py) or
    "auto" (``on_segments``).
    Deprecated (this
    release only): a sphere's or cylinder's centre as ``point``, a plane's normal as
    ``axis`` (the meaning they had), with a DeprecationWarning."""

    shape: str
    point: Sequence[float] | None = None       # plane: a point of its surface
    axis: Sequence[float] | None = None        # cylinder: the axis direction
    radius: float = 0.0
    length: float = 0.0
    friction: float = 0.0
    normal: Sequence[float] | None = None      # plane: the outward normal
    centre: Sequence[float] | None = None      # sphere, cylinder: the centre; mesh: its
    file: str | None = None                    # mesh: an STL or OBJ file      # offset
    vertices: Sequence | None = None           # mesh: (n, 3) points, or from the file
    triangles: Sequence | None = None          # mesh: (m, 3) vertex indices
    rotation: Sequence[float] | None = None    # mesh: a rotation vector (radians)
    scale: float = 1.0                         # mesh: a factor on the vertices
    contact: str = "auto"                      # "nodes" | "segments" | "auto"

    def __post_init__(self):
        old, new = ("axis", "normal") if self.shape == "plane" else ("point", "centre")
        if self.shape != "mesh" and getattr(self, old) is not None:
            if getattr(self, new) is not None:
                raise TypeError(f"Obstacle: give {new} or the deprecated {old}, not both")
            warnings.warn(f"Obstacle: a {self.shape}'s {old!r} is deprecated and goes in "
                          f"the next release: use {new} (the scene's key)",
                          DeprecationWarning, stacklevel=3)
            setattr(self, new, getattr(self, old))
            setattr(self, old, None)

    @property
    def where(self) -> Sequence[float]:
        """The plane's point or the centre (the origin if not given)."""
        where = self.point if self.shape == "plane" else self.centre
        return (0.0, 0.0, 0.0) if where is None else where

    @functools.cached_property
    def surface(self) -> Surface:
        """A mesh's checked and placed surface (MeshError naming the key at fault)."""
        return placed_surface(self.file, self.vertices, self.triangles, self.centre,
                              self.rotation, self.scale)

    @property
    def direction(self) -> Sequence[float]:
        """The plane's normal or the cylinder's axis (e_3 if not given)."""
        direction = self.normal if self.shape == "plane" else self.axis
        return (0.0, 0.0, 1.0) if direction is None else direction


PAIR_CURVES = ("segments", "smooth")     # pair_contact.py, smooth_pairs.py


@dataclass
class Spin:
    """The rod's rotation where the friction needs it (its contact point lies on the
    surface, off the centre line): the rotation q, the material angular velocity W and
    the material virtual rotation dTheta (discretisation.Unknowns) and the name of the
    rotation block."""

    q: ufl.core.expr.Expr
    W: ufl.core.expr.Expr
    dTheta: ufl.core.expr.Expr
    block: str


@dataclass
class ContactLaw:
    """The rod's radius r, the barrier's gap delta (0 < delta < r), its stiffness kappa
    (``default_stiffness``), the friction's slip tolerance eps (a velocity) and whether
    segments touch each other: of one rod (``self``), of different rods
    (``between_rods``; pair_contact.py), with Coulomb friction of coefficients
    ``self_friction`` and ``between_rods_friction`` (pair_friction.py): the keys of a
    scene's [contact].  ``self_contact`` is the deprecated name of ``self`` (this release
    only, with a DeprecationWarning)."""

    radius: float
    gap: float
    stiffness: float
    slip_tolerance: float = 1e-4
    self: bool = False              # pairs of the rod's own segments (pair_contact.py)
    between_rods: bool = False      # pairs of segments of different rods of a system
    self_friction: float = 0.0      # Coulomb's mu of self-contact (pair_friction.py)
    between_rods_friction: float = 0.0      # ... of contact between rods
    pair_curve: str = "segments"    # the pairs' curves: "segments" | "smooth" (C^1)
    obstacle_curve: str = "smooth"      # the rod's curves on thin obstacles: the same
    self_contact: bool | None = None        # deprecated: self

    def __post_init__(self):
        if self.self_contact is not None:
            if self.self:
                raise TypeError("ContactLaw: give self or the deprecated self_contact, "
                                "not both")
            warnings.warn("ContactLaw: 'self_contact' is deprecated and goes in the next "
                          "release: use self (the scene's contact.self)", DeprecationWarning,
                          stacklevel=3)
            self.self, self.self_contact = bool(self.self_contact), None


def check_contact(obstacles: Sequence[Obstacle], law: ContactLaw) -> None:
    """ValueError naming the bad entry (obstacles[k].key, contact.key)."""
    positive("contact.radius", law.radius)
    positive("contact.gap", law.gap)
    positive("contact.stiffness", law.stiffness)
    positive("contact.slip_tolerance", law.slip_tolerance)
    nonnegative("contact.self_friction", law.self_friction)
    nonnegative("contact.between_rods_friction", law.between_rods_friction)
    for key in ("pair_curve", "obstacle_curve"):
        if getattr(law, key) not in PAIR_CURVES:
            raise ValueError(f"contact.{key} must be one of {', '.join(PAIR_CURVES)}, got "
                             f"{getattr(law, key)!r}")
    if law.gap >= law.radius:
        raise ValueError(f"contact.gap must be < contact.radius ({law.radius:g}): the "
                         f"barrier acts within delta of the surface, got {law.gap:g}")
    for k, ob in enumerate(obstacles):
        name = f"obstacles[{k}]"
        if ob.shape not in SHAPES:
            raise ValueError(f"{name}.shape must be one of {', '.join(SHAPES)}, got "
                             f"{ob.shape!r}")
        nonnegative(f"{name}.friction", ob.friction)
        check_contact_mode(name, ob)
        if ob.shape == "mesh":
            positive(f"{name}.scale", ob.scale)
            try:
                ob.surface
            except MeshError as err:
                raise ValueError(f"{name}.{err.key}: {err}") from None
            continue
        keys = ("point", "normal") if ob.shape == "plane" else ("centre", "axis")
        if np.shape(ob.where) != (3,) or np.shape(ob.direction) != (3,):
            raise ValueError(f"{name}: {' and '.join(keys)} must be 3-vectors")
        if ob.shape != "sphere" and not np.linalg.norm(ob.direction) > 0:
            raise ValueError(f"{name}.{'normal' if ob.shape == 'plane' else 'axis'} must "
                             "not be zero")
        if ob.shape != "plane":
            positive(f"{name}.radius", ob.radius)
        if ob.shape == "cylinder":
            positive(f"{name}.length", ob.length)


def check_contact_mode(name: str, ob: Obstacle) -> None:
    """ValueError naming ``name``.contact if the obstacle's contact mode is not one of
    CONTACT_MODES, or "segments" on a shape it does not apply to (a plane)."""
    if ob.contact not in CONTACT_MODES:
        raise ValueError(f"{name}.contact must be one of {', '.join(CONTACT_MODES)}, got "
                         f"{ob.contact!r}")
    if ob.contact == "segments" and ob.shape not in SEGMENT_SHAPES:
        raise ValueError(f"{name}.contact = 'segments' applies to a sphere, a cylinder or "
                         f"a mesh, not a {ob.shape} (its contact acts on the nodes: "
                         "'nodes' or 'auto')")


def on_segments(ob: Obstacle, radius: float, gap: float, h: float) -> bool:
    """Whether the obstacle's barrier acts on the rod's segments (obstacle_segments.py)
    rather than its nodes: contact = "segments" (a mesh: on its sharp edges, its nodal
    law kept: obstacle_segments.fixed_segments), or "auto" for a sphere or cylinder of
    radius R that nodes h apart (the longest cell) cannot hold, h^2 >=
    4 (r + delta) (2 R + r + delta): a straight rod across it, the obstacle midway
    between two nodes, has its chord touch the body while both nodes are still beyond
    the barrier's reach r + delta (docs/contact.md, "Thin obstacles"); "auto" for a mesh
    with a convex edge that nodes h apart cannot hold (segments.chord_reaches_edge)."""
    turn = (ob.surface.convex_edges()[1] if ob.shape == "mesh" and ob.contact == "auto"
            else ())
    return segments.on_segments(ob.contact, ob.shape, ob.radius, radius + gap, h, turn)


def default_stiffness(rho_A, bending, length: float, n_cells: int, dt: float) -> float:
    """kappa from the rod and the time step: the barrier's stiffness per unit length at
    g = delta / 2, kappa b''(delta / 2), equals the inertia's rho_A / dt^2 plus the
    bending stiffness EI / h^4 of one cell (h = L / n_cells; rho_A the largest, EI the
    smallest along s): the stiffnesses Newton already resolves (docs/contact.md)."""
    s = sample_points(length)
    rho = max(np.max(np.broadcast_to(rho_A(s) if callable(rho_A) else rho_A, s.shape)), 0.0)
    A = [np.asarray(bending(si) if callable(bending) else bending, float) for si in s[::32]]
    EI = min(float(np.min(np.diag(a) if a.ndim == 2 else a[:2])) for a in A)
    h = length / n_cells
    return (rho / dt**2 + EI / h**4) / BARRIER_CURVATURE


# -- geometry: one formula for UFL (forms) and numpy (node checks) ----------------------

class _Ops:
    def __init__(self, ufl_forms: bool):
        if ufl_forms:
            self.dot, self.sqrt = ufl.dot, ufl.sqrt
            self.max, self.where, self.le, self.lt = (ufl.max_value, ufl.conditional, ufl.le,
                                                      ufl.lt)
            self.scale = lambda z, a: z * a
        else:
            self.dot = lambda a, b: np.sum(a * b, axis=-1)
            self.sqrt, self.max, self.where = np.sqrt, np.maximum, np.where
            self.le, self.lt = np.less_equal, np.less
            self.scale = lambda z, a: z[..., None] * a


UFL_OPS, NP_OPS = _Ops(True), _Ops(False)


def unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


class Pose:
    """An obstacle's shape and data (unit axis) as numbers, or as fem.Constants on
    ``mesh`` (forms of the same shapes then share their kernels: form_cache)."""

    def __init__(self, ob: Obstacle, mesh=None):
        values = {"point": np.asarray(ob.where, float), "axis": unit(ob.direction)
                  if np.linalg.norm(ob.direction) > 0 else np.array([0.0, 0.0, 1.0]),
                  "radius": float(ob.radius), "length": float(ob.length),
                  "friction": float(ob.friction)}
        self.shape = ob.shape
        for name, value in values.items():
            setattr(self, name, value if mesh is None else
                    fem.Constant(mesh, np.asarray(value, dtype=float)))


class MeshPose:
    """A mesh obstacle's surface (numbers), or (on ``mesh``, the rod's) its nodes'
    closest features as P1 fields, set by ``locate`` from the nodes' points: the contact
    law's signed distance d = n . (p - a) (a face), s |(p - a) - ((p - a) . e) e| (an edge
    of direction e; e = 0 for a vertex), triangle_mesh.Features."""

    shape = "mesh"

    def __init__(self, ob: Obstacle, mesh=None):
        self.surface = ob.surface
        self.friction = float(ob.friction) if mesh is None else fem.Constant(
            mesh, float(ob.friction))
        if mesh is None:
            return
        V3, V1 = (fem.functionspace(mesh, ("Lagrange", 1, shape)) for shape in ((3,), ()))
        self.anchor, self.normal, self.direction = (fem.Function(V3) for _ in range(3))
        self.on_face, self.sign = fem.Function(V1), fem.Function(V1)
        self.fields = (self.anchor, self.normal, self.direction, self.on_face, self.sign)

    def locate(self, points: np.ndarray) -> None:
        """The fields at the owned nodes' ``points`` (n, 3): their closest features."""
        f = self.surface.features(points)
        edge = (f.kind == 1)[:, None]
        for field, value in ((self.anchor, f.anchor), (self.normal, f.normal),
                             (self.direction, np.where(edge, f.direction, 0.0)),
                             (self.on_face, (f.kind == FACE).astype(float)),
                             (self.sign, f.sign)):
            field.x.array[: value.size] = value.ravel()
            field.x.scatter_forward()

    def distance(self, p, ops: _Ops):
        if ops is NP_OPS:
            return self.surface.signed_distance(p)
        d = p - self.anchor
        face = ufl.gt(self.on_face, 0.5)
        off = ufl.dot(d, d) - ufl.dot(d, self.direction) ** 2
        return ufl.conditional(face, ufl.dot(self.normal, d),
                               self.sign * ufl.sqrt(ufl.conditional(face, 1.0, off)))


def make_pose(ob: Obstacle, mesh=None) -> Pose | MeshPose:
    """The obstacle's Pose (a mesh's MeshPose), as numbers or on ``mesh``."""
    return MeshPose(ob, mesh) if ob.shape == "mesh" else Pose(ob, mesh)


def signed_distance(pose: Pose | MeshPose, p, ops: _Ops = UFL_OPS):
    """Distance of the point p (UFL 3-vector, or numpy (n, 3)) to the obstacle's surface,
    negative inside."""
    if pose.shape == "mesh":
        return pose.distance(p, ops)
    d, a = p - pose.point, pose.axis
    if pose.shape == "plane":
        return ops.dot(d, a)
    if pose.shape == "sphere":
        return ops.sqrt(ops.dot(d, d)) - pose.radius
    z = ops.dot(d, a)                                   # cylinder: along the axis
    radial = d - ops.scale(z, a)
    e_r = ops.sqrt(ops.dot(radial, radial)) - pose.radius
    e_z = abs(z) - pose.length / 2
    outside = ops.max(e_r, 0.0) ** 2 + ops.max(e_z, 0.0) ** 2
    inside = ops.le(ops.max(e_r, e_z), 0.0)             # sqrt(0) has no derivative
    return ops.where(inside, ops.max(e_r, e_z), ops.sqrt(ops.where(inside, 1.0, outside)))


def sweep_entry(poses: Sequence[Pose | MeshPose], A0: np.ndarray, A1: np.ndarray,
                B0: np.ndarray | None = None, B1: np.ndarray | None = None):
    """(segment, obstacle) of a segment whose straight sweep enters an obstacle (numpy
    poses: signed distance d <= 0 somewhere), or None: segment i runs from A(tau) to
    B(tau) with A(tau) = A0 + tau (A1 - A0) (each (n, 3); B as A if not given: the
    nodes' paths), its points p(sigma, tau) = A + sigma (B - A) for sigma, tau in
    [0, 1].  d is 1-Lipschitz in the point and |dp/dsigma| <= L_s = max(|B0 - A0|,
    |B1 - A1|) (|B - A| is convex in tau), |dp/dtau| <= L_t = max(|A1 - A0|, |B1 - B0|),
    so on a rectangle of the (sigma, tau) square d stays > 0 if d at its centre exceeds
    (L_s dsigma + L_t dtau) / 2; other rectangles are halved along their longer side
    (in those bounds), SWEEP_DEPTH times at most (still open after them: counted as an
    entry).  (The body, not the body thickened by the rod's radius: a rod sliding on a
    curved obstacle at a small gap has chords that cut into the gap, not into the
    body.)"""
    B0, B1 = (A0, A1) if B0 is None else (B0, B1)
    L_s = np.maximum(np.linalg.norm(B0 - A0, axis=1), np.linalg.norm(B1 - A1, axis=1))
    L_t = np.maximum(np.linalg.norm(A1 - A0, axis=1), np.linalg.norm(B1 - B0, axis=1))
    for k, pose in enumerate(poses):
        idx = np.arange(len(A0))
        s0, s1, t0, t1 = (np.full(len(idx), v) for v in (0.0, 1.0, 0.0, 1.0))
        for _ in range(SWEEP_DEPTH):
            sc, tc = (0.5 * (s0 + s1))[:, None], (0.5 * (t0 + t1))[:, None]
            A = A0[idx] + tc * (A1 - A0)[idx]
            d = signed_distance(pose, A + sc * (B0[idx] + tc * (B1 - B0)[idx] - A), NP_OPS)
            if (d <= 0).any():
                return int(idx[d <= 0][0]), k
            ds, dt = L_s[idx] * (s1 - s0), L_t[idx] * (t1 - t0)
            open_ = d <= 0.5 * (ds + dt)
            if not open_.any():
                break
            idx, s0, s1, t0, t1, ds, dt = (v[open_] for v in (idx, s0, s1, t0, t1, ds, dt))
            along_s = ds >= dt
            sm, tm = np.where(along_s, 0.5 * (s0 + s1), s1), np.where(along_s, t1,
                                                                   0.5 * (t0 + t1))
            # the first halves [s0, sm] x [t0, tm] and the second ones beyond sm (or tm)
            idx, s0, s1, t0, t1 = (np.concatenate(v) for v in (
                (idx, idx), (s0, np.where(along_s, sm, s0)), (sm, s1),
                (t0, np.where(along_s, t0, tm)), (tm, t1)))
        else:
            return int(idx[0]), k
    return None


# -- the law -------------------------------------------------------------------------------

def _beta(xi):
    """-(xi - 1)^2 ln(xi), the barrier b(g) = delta^2 beta(g / delta) on [XI_MIN, 1]."""
    return -(xi - 1.0) ** 2 * math.log(xi)


_TAYLOR = (_beta(XI_MIN),                                   # beta and its derivatives at
           -2 * (XI_MIN - 1) * math.log(XI_MIN) - (XI_MIN - 1) ** 2 / XI_MIN,   # XI_MIN
           -2 * math.log(XI_MIN) - 4 * (XI_MIN - 1) / XI_MIN + (XI_MIN - 1) ** 2 / XI_MIN**2)


def barrier(g, delta):
    """b(g) (module docstring): the IPC barrier on [g_min, delta], 0 beyond, its Taylor
    polynomial of degree 2 below g_min; delta a number or a UFL constant."""
    xi = g / delta
    exact = -(xi - 1.0) ** 2 * ufl.ln(ufl.max_value(xi, XI_MIN))
    b0, b1, b2 = _TAYLOR
    taylor = b0 + b1 * (xi - XI_MIN) + 0.5 * b2 * (xi - XI_MIN) ** 2
    return delta**2 * ufl.conditional(ufl.ge(xi, 1.0), 0.0,
                                      ufl.conditional(ufl.ge(xi, XI_MIN), exact, taylor))


def barrier_derivatives(g, delta: float):
    """(b, b', b'') of ``barrier`` at the gaps g (numpy; segment pairs, pair_contact.py)."""
    xi = np.asarray(g, float) / delta
    xc = np.clip(xi, XI_MIN, 1.0)
    ln = np.log(xc)
    exact = (-(xc - 1) ** 2 * ln, -2 * (xc - 1) * ln - (xc - 1) ** 2 / xc,
             -2 * ln - 4 * (xc - 1) / xc + (xc - 1) ** 2 / xc**2)
    b0, b1, b2 = _TAYLOR
    dxi = xi - XI_MIN
    taylor = (b0 + b1 * dxi + 0.5 * b2 * dxi**2, b1 + b2 * dxi, b2 + 0 * dxi)
    return tuple(delta ** (2 - k) * np.where(xi >= 1.0, 0.0, np.where(xi >= XI_MIN, e, t))
                 for k, (e, t) in enumerate(zip(exact, taylor)))


def mollifier(y2, ops: _Ops = UFL_OPS):
    """phi(y) / y of the friction law at y^2 = (|v_t| / eps)^2: 3/2 - y^2/2 for y < 1, 1/y
    beyond (only y^2 enters below 1: smooth at rest); UFL, or numpy with NP_OPS (segment
    pairs, pair_friction.py)."""
    return ops.where(ops.lt(y2, 1.0), 1.5 - 0.5 * y2, 1.0 / ops.sqrt(ops.max(y2, 1.0)))


class ObstacleContact:
    """The contact terms of a rod's residual and diagnostics, and the checks of its states.

    disc: the rod's discretisation (1-point rule dx_r), x: the displacement (P1), xt its
    test function, V the centre line's velocity (P1; None: quasi-static, no friction),
    spin the rotation's terms (Spin; with V).
    The barrier of the obstacles ``on_segments`` (``segment_obstacles``) acts on the
    segments (obstacle_segments.py), not in these forms; the checks cover every one."""

    def __init__(self, obstacles: Sequence[Obstacle], law: ContactLaw, disc, x, V,
                 spin: Spin | None = None):
        check_contact(obstacles, law)
        self.obstacles, self.law, self.x = list(obstacles), law, x
        self.mesh, self.dx_r = disc.mesh, disc.dx_r
        self.poses = [make_pose(ob, self.mesh) for ob in obstacles]  # UFL constants
        self.numbers = [make_pose(ob) for ob in obstacles]           # numpy values
        self.meshes = [pose for pose in self.poses if pose.shape == "mesh"]
        self.features = [f for pose in self.meshes for f in pose.fields]
        self.radius, self.gap, self.stiffness, self.slip = (
            fem.Constant(self.mesh, float(v)) for v in (law.radius, law.gap, law.stiffness,
                                                        law.slip_tolerance))
        s = ufl.SpatialCoordinate(self.mesh)[0]
        self.r = ufl.as_vector((0.0, 0.0, s)) + x           # the centre line
        P1 = fem.functionspace(self.mesh, ("Lagrange", 1))
        self.normal_force = [fem.Function(P1, name=f"normal_force_{k}")
                             for k in range(len(obstacles))]       # lagged lambda_k
        self._lambda_exprs = None
        space = x.function_space
        self._owned = space.dofmap.index_map.size_local
        self._all_nodes = space.tabulate_dof_coordinates()[:, 0]    # ghosts included
        self._nodes = self._all_nodes[: self._owned]
        cells = self.mesh.topology.index_map(1).size_local
        self._segments = space.dofmap.list[:cells]          # the owned cells' two nodes
        h = self.mesh.comm.allreduce(float(np.max(np.abs(np.diff(
            self._all_nodes[self._segments], axis=1)), initial=0.0)), op=MPI.MAX)
        self.h = h              # the longest cell (on_segments, obstacle_segments.py)
        self.segment_obstacles = [k for k, ob in enumerate(obstacles)
                                  if on_segments(ob, law.radius, law.gap, h)]
        self.nodal = [k for k, ob in enumerate(obstacles)       # a mesh's faces: nodes
                      if k not in self.segment_obstacles or ob.shape == "mesh"]
        self.V = V if any(obstacles[k].friction > 0 for k in self.nodal) else None
        self.spin = spin if self.V is not None else None
        if self.V is not None and spin is None:
            raise ValueError("obstacle friction acts at the rod's surface: it needs the "
                             "rotation's terms (spin)")
        # the P1 data of the rotation's terms, at the nodes as the fields are (_nodal)
        self._spin_fields = [] if self.spin is None else [
            f for f in extract_coefficients(
                ufl.as_vector([*self.spin.q, *self.spin.W]))
            + extract_arguments(self.spin.dTheta)
            + extract_coefficients(self.spin.dTheta)]
        self.start = None       # the nodes' points at the last commit (path check)

    # densities at a point p of the centre line (UFL), per obstacle
    def _gap(self, pose, p):
        return signed_distance(pose, p) - self.radius

    def energy_density(self, p):
        """The nodal obstacles' barrier energy per unit length at p (UFL; there is one)."""
        return sum(self.stiffness * barrier(self._gap(self.poses[k], p), self.gap)
                   for k in self.nodal)

    def force_density(self, p):
        """-d(energy density)/dp: the normal contact force per unit length at p."""
        pv = ufl.variable(p)
        return -ufl.diff(self.energy_density(pv), pv)

    def _normal_parts(self, p):
        """Per obstacle (unit outward normal n_k, normal force density lambda_k) at p."""
        out = []
        for pose in self.poses:
            pv = ufl.variable(p)
            g = self._gap(pose, pv)
            n = ufl.diff(g, pv)
            gv = ufl.variable(g)
            lam = -self.stiffness * ufl.diff(barrier(gv, self.gap), gv)
            out.append((n, lam))
        return out

    def friction_density(self, p, v, lams):
        """(force, torque): Coulomb friction per unit length at the centre line's point p
        moving with velocity v, with the lagged normal force densities ``lams`` (one per
        obstacle) there, acting at the surface point c = -r n of each obstacle (module
        docstring): the force f_t, and the torque (c x f_t) . d_3 of its couple about the
        rod's axis d_3, the component that the spin W_3 d_3 in the point's velocity
        works against."""
        f, torque = ufl.as_vector((0.0, 0.0, 0.0)), 0.0
        eps = self.slip
        parts = self._normal_parts(p)
        d3 = ufl.dot(rotation_matrix(self.spin.q), ufl.as_vector((0.0, 0.0, 1.0)))
        for k in self.nodal:        # (the segments' friction: obstacle_segments.py)
            ob, pose, lam, (n, _) = self.obstacles[k], self.poses[k], lams[k], parts[k]
            if ob.friction > 0:
                c = -self.radius * n
                v_c = v + self.spin.W[2] * ufl.cross(d3, c)
                v_t = v_c - ufl.dot(v_c, n) * n
                f_k = -pose.friction * lam * mollifier(ufl.dot(v_t, v_t) / eps**2) / eps * v_t
                f, torque = f + f_k, torque + ufl.dot(ufl.cross(c, f_k), d3)
        return f, torque

    def _friction(self, expr_of_force):
        """The trapezoidal integral of expr_of_force(f_friction, couple, v, *more) at the
        nodes (and of the rotation's terms in it: Spin)."""
        return lambda p, v, *rest: expr_of_force(
            *self.friction_density(p, v, rest[:len(self.obstacles)]), v,
            *rest[len(self.obstacles):])

    # the trapezoidal rule on the 1-point rule's midpoint: node values f -+ h/2 f_s (of
    # the fields and of the mesh obstacles' features: each node's own)
    def _nodal(self, expr_of_point, *fields):
        h = ufl.CellVolume(self.mesh)
        out = []
        for sign in (-1.0, 1.0):
            def at(f, sign=sign):
                return f + sign * h / 2 * f.dx(0)
            expr = expr_of_point(*[at(f) for f in fields])
            data = [*self.features, *self._spin_fields]
            out.append(ufl.replace(expr, {f: at(f) for f in data}) if data else expr)
        return out

    def _trapezoid(self, expr_of_point, *fields):
        a, b = self._nodal(expr_of_point, *fields)
        return 0.5 * (a + b) * self.dx_r

    def energy(self):
        """The contact energy form (trapezoidal rule: nodal contact)."""
        return self._trapezoid(self.energy_density, self.r)

    def add_to(self, F: dict, xt) -> ufl.Form | int:
        """Adds the contact forces' virtual work to F["displacement"] (the normal force as
        the derivative of ``energy``) and the friction's couple's to the rotation block;
        returns the friction's dissipation rate form (0 without friction)."""
        if self.nodal:
            F["displacement"] += ufl.derivative(self.energy(), self.x, xt)
        if self.V is None:
            return 0
        lams, spin = self.normal_force, self.spin
        F["displacement"] -= self._trapezoid(self._friction(
            lambda f, m, v, dx: ufl.dot(f, dx)), self.r, self.V, *lams, xt)
        F[spin.block] -= self._trapezoid(self._friction(
            lambda f, m, v: m * spin.dTheta[2]), self.r, self.V, *lams)
        return -self._trapezoid(self._friction(
            lambda f, m, v: ufl.dot(f, v) + m * spin.W[2]), self.r, self.V, *lams)

    def diagnostic_forms(self) -> dict:
        """contact_energy and the total contact force on the rod (normal and friction)
        of the nodal obstacles (none if every obstacle acts on the segments)."""
        if not self.nodal:
            return {}
        forms = {"contact_energy": self.energy()}
        for i, c in enumerate("xyz"):
            total = self._trapezoid(lambda p: self.force_density(p)[i], self.r)
            if self.V is not None:
                total += self._trapezoid(self._friction(lambda f, c, v: f[i]), self.r,
                                         self.V, *self.normal_force)
            forms[f"contact_force_{c}"] = total
        return forms

    # -- nodal values: gaps, checks, the lagged normal force ----------------------------

    def gaps(self) -> np.ndarray:
        """(owned nodes, obstacles) gaps of the current state."""
        p = self._positions()
        return np.stack([signed_distance(pose, p, NP_OPS) - self.law.radius
                         for pose in self.numbers], axis=-1).reshape(len(p), -1)

    def closest(self) -> tuple[float, float, int]:
        """(smallest gap, s of its node, obstacle) over all ranks."""
        g = self.gaps()
        local = (np.inf, 0.0, -1)
        if g.size:
            i, k = np.unravel_index(np.argmin(g), g.shape)
            local = (float(g[i, k]), float(self._nodes[i]), int(k))
        return min(self.mesh.comm.allgather(local))

    def nearest_obstacle(self) -> str:
        """Where a failed solve was, for step_control.step_failure: the obstacle nearest
        the centre line at the current state, with the friction's knobs if it has
        friction (a stick-slip transition sharper than Newton resolves in a step stalls
        it: a kink of a prescribed motion dragging a rod on a floor; a larger
        slip_tolerance, a smaller dt or a smooth_step let it through, docs/contact.md)."""
        g, s, k = self.closest()
        said = (f"obstacles[{k}] nearest the centre line at s = {s:.4g}, gap {g:.3g} (the "
                f"barrier acts below {self.law.gap:g})")
        mu = self.obstacles[k].friction
        if mu > 0:
            said += (f"; with friction mu = {mu:g} Newton may stall where the rod turns "
                     f"from sticking to sliding within a step: a larger "
                     f"contact.slip_tolerance (now {self.law.slip_tolerance:.3g}), a smaller "
                     f"time.dt or a smooth_step instead of a ramp's kink in a prescribed "
                     f"motion lets it through")
        return said

    def check_initial(self) -> None:
        """InitialOverlap if the state (at t = 0) has a node within r of an obstacle."""
        self.locate()
        g, s, k = self.closest()
        if g <= 0:
            raise InitialOverlap.at("centre line", s, g, k, self.law.gap,
                                    self.obstacles[k].shape)

    def check_state(self, prescribed: dict[float, str] | None = None) -> str | None:
        """A reason to reject a converged step: a node at or inside an obstacle, or a
        segment whose sweep from the last committed state (its nodes on straight paths)
        entered one's body (passed through a thin obstacle or across a sharp edge within
        the step, or cuts into the body between its nodes: sweep_entry).  ``prescribed``:
        {s of an end whose displacement is prescribed: its key}; such an end inside is
        driven there by its motion, which no barrier stiffness can stop."""
        g, s, k = self.closest()
        if g <= 0:
            key = next((key for s_end, key in (prescribed or {}).items()
                        if abs(s_end - s) <= 1e-9 * max(abs(s_end), 1.0)), None)
            if key is not None:
                return (f"the prescribed motion {key} drives its end (s = {s:.4g}) into "
                        f"obstacles[{k}] (gap {g:.3g}): the barrier cannot hold back a "
                        f"prescribed end; stop the motion before the obstacle or move it")
            return (f"the centre line at s = {s:.4g} is {abs(g):.3g} inside obstacles[{k}] "
                    f"(gap {g:.3g}; the barrier was overcome: raise contact.stiffness)")
        if self.start is None:
            return None
        P0, P1 = self.start, self._positions(ghosts=True)
        a, b = self._segments[:, 0], self._segments[:, 1]
        hit = sweep_entry(self.numbers, P0[a], P1[a], P0[b], P1[b])
        found = self.mesh.comm.allgather(None if hit is None else (float(np.mean(
            self._all_nodes[self._segments[hit[0]]])), hit[1]))
        hit = next((h for h in found if h is not None), None)
        if hit is None:
            return None
        return (f"the centre line near s = {hit[0]:.4g} passed through obstacles[{hit[1]}] "
                "during the step (the sweep of a segment entered it: the step is cut)")

    def _positions(self, ghosts: bool = False) -> np.ndarray:
        """(owned nodes, 3) the centre line's points (``ghosts``: of all the rank's nodes,
        the ghosts' values brought from their owners)."""
        if not ghosts:
            x = self.x.x.array.reshape(-1, 3)[: self._owned]
            return x + np.outer(self._nodes, (0.0, 0.0, 1.0))
        self.x.x.scatter_forward()
        return self.x.x.array.reshape(-1, 3) + np.outer(self._all_nodes, (0.0, 0.0, 1.0))

    def commit(self) -> None:
        """After an accepted step (and at the start): its points start the next step's
        path check."""
        self.locate()
        self.start = self._positions(ghosts=True)

    def update_normal_forces(self) -> None:
        """lambda_k := the normal force density of the current state at the nodes (after
        an accepted step: the friction's lagged normal force)."""
        if self.V is None:
            return
        self.locate()
        if self._lambda_exprs is None:
            points = compat.interpolation_points(self.normal_force[0].function_space)
            self._lambda_exprs = [fem.Expression(lam, points)
                                  for _, lam in self._normal_parts(self.r)]
        for lam, expr in zip(self.normal_force, self._lambda_exprs):
            lam.interpolate(expr)

    def locate(self, owned_displacement: np.ndarray | None = None) -> None:
        """The mesh obstacles' features at the nodes of the displacement (owned values;
        default the current one): before the forms are assembled at it."""
        if not self.meshes:
            return
        x = (self.x.x.array[: 3 * self._owned] if owned_displacement is None
             else owned_displacement).reshape(-1, 3)
        points = x + np.outer(self._nodes, (0.0, 0.0, 1.0))
        for pose in self.meshes:
            pose.locate(points)

    @property
    def term(self) -> "FeatureTerm | None":
        """With mesh obstacles: the term (fem/assembly add_terms) that locates the
        features at every residual's state before its forms are assembled."""
        return FeatureTerm(self) if self.meshes else None

    def force_observable(self):
        """The contact force density (normal + friction) at a point of the rod (UFL; at
        the vertices the nodal value)."""
        if not self.nodal:
            return ufl.as_vector((0.0, 0.0, 0.0))
        f = self.force_density(self.r)
        if self.V is not None:
            f += self.friction_density(self.r, self.V, self.normal_force)[0]
        return f


class FeatureTerm:
    """ObstacleContact's mesh features in a solve (fem/assembly add_terms): the problem's
    term, bound to each system that holds the displacement."""

    def __init__(self, contact: ObstacleContact):
        self.contact = contact

    def bind(self, system) -> "BoundFeatures":
        return BoundFeatures(self, system)

    def for_step(self, *stages):
        """Per-step schemes evaluate the residual at several stage states, the features
        are one node's for one state: refused."""
        raise ValueError("a mesh obstacle ([[obstacles]] shape = \"mesh\") is solved by "
                         "generalized-alpha or quasi-statically, not by a per-step scheme "
                         "(time.scheme): its nodes' closest features are those of one "
                         "state")


class BoundFeatures:
    """FeatureTerm in one assembled system: ``prepare`` locates the features at the
    system's state x (its displacement rows; the displacement as it is if the system
    does not solve for it, e.g. the start's accelerations)."""

    def __init__(self, term: FeatureTerm, system):
        contact = term.contact
        self.contact = contact
        held = [k for k, y in enumerate(system.groups[0]) if y is contact.x]
        self.rows = (system.rows_of(held[0], np.arange(3 * contact._owned))
                     if held else None)

    def prepare(self, x_owned: np.ndarray) -> None:
        self.contact.locate(None if self.rows is None else x_owned[self.rows])
