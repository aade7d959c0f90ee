"""Contact of the rod with rigid obstacles (issue 26; docs/contact.md): planes
(half-spaces), spheres and finite cylinders touching the rod's centre line thickened by
its radius r, with a smooth barrier of stated gap delta and Coulomb friction.

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
               centre line's velocity tangent to the obstacle and eps the slip tolerance:
               a rod held by static friction creeps at less than eps.

The normal force enters the residual as the derivative of the contact energy (its
Jacobian by UFL: consistent), the friction force as a force; the contact energy joins
K + Psi in the power balance, the friction's power -f_t . v_t >= 0 the dissipation.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Sequence

import dolfinx.fem as fem
import numpy as np
import ufl

from ..fem import compat
from ..checks import nonnegative, positive, sample_points

SHAPES = ("plane", "sphere", "cylinder")
XI_MIN = 1e-4             # g_min / delta: the barrier's exact range is [g_min, delta]
BARRIER_CURVATURE = 2 * math.log(2) + 5.0   # b''(delta / 2) (dimensionless)
PATH_DEPTH = 24           # bisections of a node's path in a step (path_entry)


class InitialOverlap(ValueError):
    """The rod's initial state meets an obstacle (``obstacle``: its index)."""

    def __init__(self, reason: str, obstacle: int):
        super().__init__(reason)
        self.obstacle = obstacle


@dataclass
class Obstacle:
    """A rigid obstacle, in the keys of a scene's [[obstacles]]: ``shape`` "plane" (the
    half-space behind ``point`` against the outward ``normal``), "sphere" (``radius``
    around ``centre``) or "cylinder" (``radius``, ``length`` along ``axis`` through its
    ``centre``); ``friction`` the Coulomb coefficient mu >= 0.  Deprecated (this
    release only): a sphere's or cylinder's centre as ``point``, a plane's normal as
    ``axis`` (the meaning they had), with a DeprecationWarning."""

    shape: str
    point: Sequence[float] | None = None       # plane: a point of its surface
    axis: Sequence[float] | None = None        # cylinder: the axis direction
    radius: float = 0.0
    length: float = 0.0
    friction: float = 0.0
    normal: Sequence[float] | None = None      # plane: the outward normal
    centre: Sequence[float] | None = None      # sphere, cylinder: the centre

    def __post_init__(self):
        old, new = ("axis", "normal") if self.shape == "plane" else ("point", "centre")
        if getattr(self, old) is not None:
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

    @property
    def direction(self) -> Sequence[float]:
        """The plane's normal or the cylinder's axis (e_3 if not given)."""
        direction = self.normal if self.shape == "plane" else self.axis
        return (0.0, 0.0, 1.0) if direction is None else direction


PAIR_CURVES = ("segments", "smooth")     # pair_contact.py, smooth_pairs.py


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
    if law.pair_curve not in PAIR_CURVES:
        raise ValueError(f"contact.pair_curve must be one of {', '.join(PAIR_CURVES)}, got "
                         f"{law.pair_curve!r}")
    if law.gap >= law.radius:
        raise ValueError(f"contact.gap must be < contact.radius ({law.radius:g}): the "
                         f"barrier acts within delta of the surface, got {law.gap:g}")
    for k, ob in enumerate(obstacles):
        name = f"obstacles[{k}]"
        if ob.shape not in SHAPES:
            raise ValueError(f"{name}.shape must be one of {', '.join(SHAPES)}, got "
                             f"{ob.shape!r}")
        nonnegative(f"{name}.friction", ob.friction)
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


def signed_distance(pose: Pose, p, ops: _Ops = UFL_OPS):
    """Distance of the point p (UFL 3-vector, or numpy (n, 3)) to the obstacle's surface,
    negative inside."""
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


def path_entry(poses: Sequence[Pose], P0: np.ndarray, P1: np.ndarray):
    """(node, obstacle) of a node whose straight path P0 -> P1 ((n, 3) each) enters an
    obstacle (numpy poses: signed distance d <= 0), or None.  d is 1-Lipschitz in the
    point, so on [a, b] of the path's parameter it stays > 0 if d(a) + d(b) > |P1 - P0|
    (b - a); other intervals are bisected (PATH_DEPTH times at most; still open after
    them: counted as an entry).  (The body, not the body thickened by the rod's radius:
    a node sliding on a curved obstacle at a small gap has chords that cut into the
    gap, not into the body.)"""
    move = np.linalg.norm(P1 - P0, axis=1)
    for k, pose in enumerate(poses):
        def gap(tau, i):
            point = P0[i] + tau[:, None] * (P1 - P0)[i]
            return signed_distance(pose, point, NP_OPS)
        idx = np.arange(len(P0))
        a, b = np.zeros(len(idx)), np.ones(len(idx))
        ga, gb = gap(a, idx), gap(b, idx)
        for _ in range(PATH_DEPTH):
            inside = np.minimum(ga, gb) <= 0
            if inside.any():
                return int(idx[inside][0]), k
            open_ = ga + gb <= move[idx] * (b - a)
            if not open_.any():
                break
            idx, a, b, ga, gb = idx[open_], a[open_], b[open_], ga[open_], gb[open_]
            m = 0.5 * (a + b)
            gm = gap(m, idx)
            idx, a, b, ga, gb = (np.concatenate(v) for v in
                                 ((idx, idx), (a, m), (m, b), (ga, gm), (gm, gb)))
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
    test function, V the centre line's velocity (P1; None: quasi-static, no friction)."""

    def __init__(self, obstacles: Sequence[Obstacle], law: ContactLaw, disc, x, V):
        check_contact(obstacles, law)
        self.obstacles, self.law, self.x = list(obstacles), law, x
        self.mesh, self.dx_r = disc.mesh, disc.dx_r
        self.poses = [Pose(ob, self.mesh) for ob in obstacles]      # UFL constants
        self.numbers = [Pose(ob) for ob in obstacles]               # numpy values
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
        self._nodes = space.tabulate_dof_coordinates()[: self._owned, 0]
        self.V = V if any(ob.friction > 0 for ob in obstacles) else None
        self.start = None       # the nodes' points at the last commit (path check)

    # densities at a point p of the centre line (UFL), per obstacle
    def _gap(self, pose, p):
        return signed_distance(pose, p) - self.radius

    def energy_density(self, p):
        return sum(self.stiffness * barrier(self._gap(pose, p), self.gap)
                   for pose in self.poses)

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
        """Coulomb friction per unit length at p moving with velocity v, with the lagged
        normal force densities ``lams`` (one per obstacle) there."""
        f = ufl.as_vector((0.0, 0.0, 0.0))
        eps = self.slip
        for ob, pose, lam, (n, _) in zip(self.obstacles, self.poses, lams,
                                         self._normal_parts(p)):
            if ob.friction > 0:
                v_t = v - ufl.dot(v, n) * n
                f -= pose.friction * lam * mollifier(ufl.dot(v_t, v_t) / eps**2) / eps * v_t
        return f

    def _friction(self, expr_of_force):
        """The trapezoidal integral of expr_of_force(f_friction, v, *more) at the nodes."""
        return lambda p, v, *rest: expr_of_force(
            self.friction_density(p, v, rest[:len(self.obstacles)]), v,
            *rest[len(self.obstacles):])

    # the trapezoidal rule on the 1-point rule's midpoint: node values f -+ h/2 f_s
    def _nodal(self, expr_of_point, *fields):
        h = ufl.CellVolume(self.mesh)
        return [expr_of_point(*[f + sign * h / 2 * f.dx(0) for f in fields])
                for sign in (-1.0, 1.0)]

    def _trapezoid(self, expr_of_point, *fields):
        a, b = self._nodal(expr_of_point, *fields)
        return 0.5 * (a + b) * self.dx_r

    def energy(self):
        """The contact energy form (trapezoidal rule: nodal contact)."""
        return self._trapezoid(self.energy_density, self.r)

    def add_to(self, F: dict, xt) -> ufl.Form | int:
        """Adds the contact forces' virtual work to F["displacement"] (the normal force as
        the derivative of ``energy``); returns the friction's dissipation rate form (0
        without friction)."""
        F["displacement"] += ufl.derivative(self.energy(), self.x, xt)
        if self.V is None:
            return 0
        lams = self.normal_force
        F["displacement"] -= self._trapezoid(self._friction(lambda f, v, w: ufl.dot(f, w)),
                                             self.r, self.V, *lams, xt)
        return -self._trapezoid(self._friction(lambda f, v: ufl.dot(f, v)),
                                self.r, self.V, *lams)

    def diagnostic_forms(self) -> dict:
        """contact_energy and the total contact force on the rod (normal and friction)."""
        forms = {"contact_energy": self.energy()}
        for i, c in enumerate("xyz"):
            total = self._trapezoid(lambda p: self.force_density(p)[i], self.r)
            if self.V is not None:
                total += self._trapezoid(self._friction(lambda f, v: f[i]), self.r, self.V,
                                         *self.normal_force)
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

    def check_initial(self) -> None:
        """InitialOverlap if the state (at t = 0) has a node within r of an obstacle."""
        g, s, k = self.closest()
        if g <= 0:
            raise InitialOverlap(f"the rod's centre line at s = {s:.4g} is {-g:.3g} closer "
                                 f"to obstacles[{k}] than the rod's radius at t = 0: move "
                                 "the obstacle or the rod", k)

    def check_state(self) -> str | None:
        """A reason to reject a converged step: a node at or inside an obstacle, or a
        node whose straight path from the last committed state entered one's body
        (jumped through a thin obstacle within the step: path_entry)."""
        g, s, k = self.closest()
        if g <= 0:
            return (f"the centre line at s = {s:.4g} is {-g:.3g} inside obstacles[{k}] "
                    f"(gap {g:.3g}; the barrier was overcome: raise contact.stiffness)")
        if self.start is None:
            return None
        hit = path_entry(self.numbers, self.start, self._positions())
        found = self.mesh.comm.allgather(None if hit is None else
                                         (float(self._nodes[hit[0]]), hit[1]))
        hit = next((h for h in found if h is not None), None)
        if hit is None:
            return None
        return (f"the centre line at s = {hit[0]:.4g} passed through obstacles[{hit[1]}] "
                "during the step (a node's path entered it: the step is cut)")

    def _positions(self) -> np.ndarray:
        """(owned nodes, 3) the centre line's points."""
        x = self.x.x.array.reshape(-1, 3)[: self._owned]
        return x + np.outer(self._nodes, (0.0, 0.0, 1.0))

    def commit(self) -> None:
        """After an accepted step (and at the start): its points start the next step's
        path check."""
        self.start = self._positions()

    def update_normal_forces(self) -> None:
        """lambda_k := the normal force density of the current state at the nodes (after
        an accepted step: the friction's lagged normal force)."""
        if self.V is None:
            return
        if self._lambda_exprs is None:
            points = compat.interpolation_points(self.normal_force[0].function_space)
            self._lambda_exprs = [fem.Expression(lam, points)
                                  for _, lam in self._normal_parts(self.r)]
        for lam, expr in zip(self.normal_force, self._lambda_exprs):
            lam.interpolate(expr)

    def force_observable(self):
        """The contact force density (normal + friction) at a point of the rod (UFL; at
        the vertices the nodal value)."""
        f = self.force_density(self.r)
        if self.V is not None:
            f += self.friction_density(self.r, self.V, self.normal_force)
        return f
