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
               Directional friction (an obstacle's ``directional_friction``, PyElastica's
               AnisotropicFrictionalPlane): mu v_t becomes mu_a (v_t . a) a + mu_l
               (v_t . b) b, a the rod's axis d_3 projected on the obstacle's tangent
               plane and normalised, b = n x a, mu_l the lateral coefficient, mu_a the
               forward one where the point slips along +a (towards the rod's end s = L),
               the backward one along -a, blended by v_a / sqrt(v_a^2 + eps^2) (v_a =
               v_t . a): equal coefficients give the isotropic law; f_t . v_t <= 0.

The normal force enters the residual as the derivative of the contact energy (its
Jacobian by UFL: consistent), the friction force and torque as the virtual work
f_t . dx + ((c x f_t) . d_3) dTheta_3 (their Jacobian by UFL too, through the
integrator's rates); the contact energy joins K + Psi in the power balance, the
friction's power -f_t . (v + W_3 d_3 x c) >= 0 the dissipation.
"""

from __future__ import annotations

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
from . import obstacle_shapes, segments
from .obstacle_shapes import (NP_OPS, SHAPES, InitialOverlap, MeshPose, Obstacle, Ops, Pose,
                              check_contact_mode, signed_distance, sweep_entry)
from .barrier import TAYLOR, XI_MIN, barrier_derivatives
from .obstacle_shapes import gaps as obstacle_gaps
from .triangle_mesh import FACE, MeshError

BARRIER_CURVATURE = 2 * math.log(2) + 5.0   # b''(delta / 2) (dimensionless)


PAIR_CURVES = ("segments", "smooth")     # pair_contact.py, smooth_pairs.py
DIRECTIONS = ("forward", "backward", "lateral")     # an obstacle's directional friction


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
        for side, mu in zip(DIRECTIONS, ob.directional_friction or ()):
            nonnegative(f"{name}.friction.{side}", mu)
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


def on_segments(ob: Obstacle, radius: float, gap: float, h: float) -> bool:
    """Whether the obstacle's barrier acts on the rod's segments (obstacle_segments.py)
    rather than its nodes: contact = "segments" (a mesh: on its sharp edges, its nodal
    law kept: obstacle_shapes.fixed_segments), or "auto" for a sphere or cylinder of
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


# -- geometry: one formula for UFL (forms) and numpy (node checks): obstacle_shapes.py --

UFL_OPS = Ops(ufl.dot, ufl.sqrt, ufl.max_value, ufl.conditional, ufl.le, ufl.lt,
              lambda z, a: z * a)


class MeshFields(MeshPose):
    """A mesh obstacle on ``mesh`` (the rod's): its nodes' closest features as P1 fields,
    set by ``locate`` from the nodes' points: the contact law's signed distance
    d = n . (p - a) (a face), s |(p - a) - ((p - a) . e) e| (an edge of direction e;
    e = 0 for a vertex), triangle_mesh.Features."""

    def __init__(self, ob: Obstacle, mesh):
        super().__init__(ob)
        self.friction = fem.Constant(mesh, float(ob.friction))
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

    def distance(self, p, ops: Ops):
        if ops is NP_OPS:
            return super().distance(p, ops)
        d = p - self.anchor
        face = ufl.gt(self.on_face, 0.5)
        off = ufl.dot(d, d) - ufl.dot(d, self.direction) ** 2
        return ufl.conditional(face, ufl.dot(self.normal, d),
                               self.sign * ufl.sqrt(ufl.conditional(face, 1.0, off)))


def make_pose(ob: Obstacle, mesh=None) -> Pose | MeshPose:
    """The obstacle's Pose (a mesh's MeshPose), as numbers or on ``mesh``."""
    if mesh is None:
        return obstacle_shapes.make_pose(ob)
    if ob.shape == "mesh":
        return MeshFields(ob, mesh)
    return Pose(ob, lambda value: fem.Constant(mesh, np.asarray(value, dtype=float)))


# -- the law -------------------------------------------------------------------------------

def barrier(g, delta):
    """b(g) (module docstring): the IPC barrier on [g_min, delta], 0 beyond, its Taylor
    polynomial of degree 2 below g_min; delta a number or a UFL constant."""
    xi = g / delta
    exact = -(xi - 1.0) ** 2 * ufl.ln(ufl.max_value(xi, XI_MIN))
    b0, b1, b2 = TAYLOR
    taylor = b0 + b1 * (xi - XI_MIN) + 0.5 * b2 * (xi - XI_MIN) ** 2
    return delta**2 * ufl.conditional(ufl.ge(xi, 1.0), 0.0,
                                      ufl.conditional(ufl.ge(xi, XI_MIN), exact, taylor))


REST_TOLERANCE = 1e-6     # rest_on_barriers: a move below 1e-6 delta is none
REST_PASSES = 40          # ... at most (each halves the imbalance of a rod lying flat)


def carrying_gap(load, delta: float) -> np.ndarray:
    """The gaps g in (XI_MIN delta, delta) at which the barrier's force per length per
    stiffness, -b'(g), is ``load`` (> 0; numpy): -b' decreases from XI_MIN delta to 0 at
    delta, so bisection on xi = g / delta (60 halvings: to round-off)."""
    lo, hi = np.full(np.shape(load), XI_MIN), np.ones(np.shape(load))
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        above = -barrier_derivatives(mid * delta, delta)[1] > load
        lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)
    return 0.5 * (lo + hi) * delta


def mollifier(y2, ops: Ops = UFL_OPS):
    """phi(y) / y of the friction law at y^2 = (|v_t| / eps)^2: 3/2 - y^2/2 for y < 1, 1/y
    beyond (only y^2 enters below 1: smooth at rest); UFL, or numpy with NP_OPS (segment
    pairs, pair_friction.py)."""
    return ops.where(ops.lt(y2, 1.0), 1.5 - 0.5 * y2, 1.0 / ops.sqrt(ops.max(y2, 1.0)))


class ObstacleContact:
    """The contact terms of a rod's residual and diagnostics, and the checks of its states.

    disc: the rod's discretisation (1-point rule dx_r), x: the displacement (P1), xt its
    test function, V the centre line's velocity (P1; None: quasi-static, no friction),
    spin the rotation's terms (Spin; with V), ``accelerations`` those of V and of the
    spin's W (rotation vectors) or None: with friction, the friction then reads the
    velocities V + tau dV/dt, W + tau dW/dt, tau the Constant ``lookahead`` (0; the
    integrator's first step while it solves for the starting accelerations:
    fem/problem.SecondOrderProblem.friction_lookahead).
    The barrier of the obstacles ``on_segments`` (``segment_obstacles``) acts on the
    segments (obstacle_segments.py), not in these forms; the checks cover every one."""

    def __init__(self, obstacles: Sequence[Obstacle], law: ContactLaw, disc, x, V,
                 spin: Spin | None = None, accelerations: tuple | None = None):
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
        self.directional = {k: fem.Constant(self.mesh, np.asarray(ob.directional_friction))
                            for k, ob in enumerate(obstacles)
                            if ob.directional_friction is not None}
        self.V = V if any(obstacles[k].friction > 0 for k in self.nodal) else None
        self.spin = spin if self.V is not None else None
        if self.V is not None and spin is None:
            raise ValueError("obstacle friction acts at the rod's surface: it needs the "
                             "rotation's terms (spin)")
        self.lookahead = None
        self.velocity, self.acceleration = V, None if accelerations is None else \
            accelerations[0]                # (the start's rest_on_barriers)
        if self.V is not None and accelerations is not None:
            self.lookahead = tau = fem.Constant(self.mesh, 0.0)
            A, alpha = accelerations
            self.V = self.V + tau * A
            self.spin = Spin(spin.q, spin.W + tau * alpha, spin.dTheta, spin.block)
        # the P1 data of the rotation's terms, at the nodes as the fields are (_nodal)
        self._spin_fields = [] if self.spin is None else [
            f for f in extract_coefficients(
                ufl.as_vector([*self.spin.q, *self.spin.W]))
            + extract_arguments(self.spin.dTheta)
            + extract_coefficients(self.spin.dTheta)]
        self.start = None       # the nodes' points at the last commit (path check)

    # densities at a point p of the centre line (UFL), per obstacle
    def _gap(self, pose, p):
        return signed_distance(pose, p, UFL_OPS) - self.radius

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
                f_k = -lam * mollifier(ufl.dot(v_t, v_t) / eps**2) / eps * (
                    self._resisted(k, v_t, n, d3) if k in self.directional
                    else pose.friction * v_t)
                f, torque = f + f_k, torque + ufl.dot(ufl.cross(c, f_k), d3)
        return f, torque

    def _resisted(self, k, v_t, n, d3):
        """mu v_t of directional friction (module docstring): the slip v_t split along the
        rod's axis on the surface, a, and across it, b = n x a, each times its
        coefficient; a rod standing on the surface (d_3 along n) has no axis there and
        no friction."""
        forward, backward, lateral = (self.directional[k][i] for i in range(3))
        a = d3 - ufl.dot(d3, n) * n
        a = a / ufl.sqrt(ufl.dot(a, a) + 1e-24)
        b = ufl.cross(n, a)
        v_a, v_b = ufl.dot(v_t, a), ufl.dot(v_t, b)
        along = v_a / ufl.sqrt(v_a**2 + self.slip**2)      # the slip's sign along a, smoothed
        mu_a = 0.5 * (forward + backward) + 0.5 * (forward - backward) * along
        return mu_a * v_a * a + lateral * v_b * b

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
        return obstacle_gaps(self.numbers, self._positions(), self.law.radius)

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

    def rest_on_barriers(self, mass: np.ndarray) -> tuple[float, float]:
        """One pass of the start's rest on the barriers, its accelerations solved: each
        owned node at rest within the barrier of a nodal obstacle (0 < g < delta; the
        nearest one) moved along the obstacle's normal n towards the gap at which the
        barrier carries what presses the node there, so that a rod laid at rest anywhere
        within the barrier rests on it instead of being thrown off (the default
        stiffness follows 1 / dt^2: at dt = 1e-3 the barrier at delta / 2 pushes with 19
        times the weight; docs/contact.md).  The barrier's force per length
        lambda = -kappa b'(g) is corrected by half the node's normal imbalance,
        lambda - rho_A (a . n) / 2 (``mass``: rho_A at the owned nodes; half: the
        consistent mass answers a node's own force by up to 3 times the lumped mass's
        acceleration), and the gap follows it (-b' decreases on (0, delta)); a node that
        nothing presses in (lambda <= 0) goes to delta, out of reach; one the barrier
        cannot carry above XI_MIN delta stays.  (The largest move / delta, the largest
        normal imbalance rho_A |a . n| of those nodes), over all ranks."""
        move = imbalance = 0.0
        if self.nodal and self.acceleration is not None:
            points, delta, kappa = self._positions(), self.law.gap, self.law.stiffness
            nodal = [self.numbers[k] for k in self.nodal]
            g = obstacle_gaps(nodal, points, self.law.radius)
            k = np.argmin(g, axis=1)
            gap = g[np.arange(len(k)), k]
            n = self._normals(nodal, points, k)
            owned = 3 * self._owned
            a = self.acceleration.x.array[:owned].reshape(-1, 3)
            v = self.velocity.x.array[:owned].reshape(-1, 3)
            a_n = np.einsum("ij,ij->i", a, n)
            lam = kappa * -barrier_derivatives(gap, delta)[1] - 0.5 * mass * a_n
            most = kappa * -barrier_derivatives(XI_MIN * delta, delta)[1]
            rest = (gap > 0) & (gap < delta) & ~np.any(v, axis=1) & (a_n != 0) & (lam < most)
            target = np.where(lam > 0, carrying_gap(np.maximum(lam, 0.0) / kappa, delta),
                              delta)
            step = np.where(rest, target - gap, 0.0)
            self.x.x.array[:owned] += (step[:, None] * n).ravel()
            self.x.x.scatter_forward()
            move = float(np.max(np.abs(step), initial=0.0)) / delta
            imbalance = float(np.max(np.where(rest, np.abs(mass * a_n), 0.0), initial=0.0))
        comm = self.mesh.comm
        return comm.allreduce(move, op=MPI.MAX), comm.allreduce(imbalance, op=MPI.MAX)

    def _normals(self, poses, points: np.ndarray, nearest: np.ndarray) -> np.ndarray:
        """(nodes, 3) the outward normal of obstacle poses[nearest[i]] at points[i]: the
        gradient of its signed distance (central differences, a 1e-7 r step)."""
        step = 1e-7 * self.law.radius
        rows = np.arange(len(points))
        return np.stack([(obstacle_gaps(poses, points + step * e, 0.0)[rows, nearest]
                          - obstacle_gaps(poses, points - step * e, 0.0)[rows, nearest])
                         / (2 * step) for e in np.eye(3)], axis=1)

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

    def gap_keeping(self) -> "GapKeeping":
        """The term (fem/assembly add_terms) that shortens Newton's updates so that no
        node comes closer to a nodal obstacle than a share of its gap (a settle in
        contact, rod/initial_state.py)."""
        return GapKeeping(self)

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


KEPT_GAP = 0.1      # GapKeeping: an update keeps every node's gap above this share of it


class GapKeeping:
    """Newton's updates shortened so that every node keeps KEPT_GAP of its gap to each
    nodal obstacle, or loses at most (1 - KEPT_GAP) XI_MIN delta of a gap already in the
    barrier's Taylor range (as segment pairs' step_fraction, pair_contact.py): a node
    approaches an obstacle in steps that shrink with its gap, so Newton's iterates never
    reach deep into the barrier, where its Taylor polynomial lets them through.  Off
    (``active`` False) it leaves every update as it is.  A term of fem/assembly
    add_terms; ``step_factor`` is collective (the same factor on every rank)."""

    def __init__(self, contact: ObstacleContact):
        self.contact, self.active = contact, False

    def bind(self, system) -> "GapKeeping":
        held = [k for k, y in enumerate(system.groups[0]) if y is self.contact.x]
        self.rows = system.rows_of(held[0], np.arange(3 * self.contact._owned))
        return self

    def limit_step(self, x_owned: np.ndarray, y_owned: np.ndarray) -> None:
        """Newton's update x - y (PETSc's sign) scaled down in place (step_factor)."""
        alpha = self.step_factor(x_owned, y_owned)
        if alpha < 1.0:
            y_owned *= alpha

    def step_factor(self, x_owned: np.ndarray, y_owned: np.ndarray) -> float:
        """The largest 2^-k (k < 60) by which the update x - y keeps the nodes' gaps
        (class docstring); 1 when off."""
        c = self.contact
        if not self.active or not c.nodal:
            return 1.0
        nodal = [c.numbers[k] for k in c.nodal]
        s_e3 = np.outer(c._nodes, (0.0, 0.0, 1.0))
        u, du = x_owned[self.rows].reshape(-1, 3), y_owned[self.rows].reshape(-1, 3)
        g0 = obstacle_gaps(nodal, u + s_e3, c.law.radius)
        floor = np.minimum(KEPT_GAP * g0, g0 - (1 - KEPT_GAP) * XI_MIN * c.law.gap)
        alpha = 1.0
        for _ in range(60):
            if np.all(obstacle_gaps(nodal, u - alpha * du + s_e3, c.law.radius) >= floor):
                break
            alpha *= 0.5
        return c.mesh.comm.allreduce(alpha, op=MPI.MIN)
