"""Loads on the rod (PyElastica's ``external_forces``): end, distributed and point forces
and couples, dead or follower, with their histories, active bending moments (a muscle's,
PyElastica's MuscleTorques: ``TravellingWave``), and linear drag: f = -c dr/dt, or anisotropic
f = -R C R^T dr/dt (a fluid's resistive force, PyElastica's SlenderBodyTheory; C turned
onto the centre line's tangent and per current length: _fluid_force).

Their virtual work enters the balance blocks (balance.force_work, balance.couple_work);
the same densities tested with the velocities (V, W) give the power of the loads.  An
active moment M (per section, not per length: a distributed load of kind "moment") works
as the sections' own moment does, with the opposite sign: -int M . delta u ds, M in
material components (R^T M for a dead one), so that a rod at rest under it alone has
m = M, i.e. its curvature u = u_ref + B^-1 M for the quadratic energy; its power is
int M . u_t ds.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import dolfinx.fem as fem
import numpy as np
import ufl

from .. import loads as load_histories
from ..theory import balance
from ..theory.rotations import rotation_matrix
from ..checks import end_name
from ..fem.fe_model import ENDS
from ..fem.problem import TimeDependentValue
from .discretisation import Discretisation, Unknowns
from .material import DAMPING, DRAG_TENSOR, is_zero, scalars


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
    """A force or couple per unit reference length, or an active bending moment of the
    sections ("moment": module docstring): value(s) * history(t)."""

    kind: str                        # "force", "couple" or "moment"
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


@dataclass
class TravellingWave:
    """A muscle's travelling wave of active bending moment (PyElastica's MuscleTorques):

        M(s, t) = ramp(t) beta(sigma) sin(2 pi (t / period - sigma / wave_length) + phase) axis,

    sigma the arc length from the end ``origin`` ("start": sigma = s, "end": sigma = L -
    s), the wave running away from it; ramp(t) = min(1, t / ramp) (1 if ramp = 0);
    beta a number (N m) or the control values of a clamped cubic B-spline over sigma / L
    (uniform knots, PyElastica's b_coeff with with_spline); ``axis`` spatial (dead) or
    material (``follower``).  ``loads(L)``: its two DistributedLoads of kind "moment",
    sin(w t - k sigma + phase) = sin(w t) cos(k sigma - phase) - cos(w t) sin(k sigma -
    phase), each a profile in s times a history in t."""

    axis: Sequence[float]
    amplitude: float | Sequence[float]
    period: float
    wave_length: float
    phase: float = 0.0
    ramp: float = 0.0
    origin: str = "start"
    follower: bool = False

    def check(self) -> None:
        for name in ("period", "wave_length"):
            if not (np.isfinite(getattr(self, name)) and getattr(self, name) > 0):
                raise ValueError(f"TravellingWave {name} must be > 0, got "
                                 f"{getattr(self, name)!r}")
        if not (np.isfinite(self.ramp) and self.ramp >= 0):
            raise ValueError(f"TravellingWave ramp must be >= 0, got {self.ramp!r}")
        if self.origin not in ENDS:
            raise ValueError(f"TravellingWave origin must be 'start' or 'end', got "
                             f"{self.origin!r}")
        if np.shape(self.axis) != (3,) or not np.linalg.norm(self.axis) > 0:
            raise ValueError(f"TravellingWave axis must be a non-zero 3-vector, got "
                             f"{self.axis!r}")
        beta = np.atleast_1d(np.asarray(self.amplitude, float))
        if beta.ndim != 1 or beta.size in (2, 3) or not np.all(np.isfinite(beta)):
            raise ValueError("TravellingWave amplitude must be a number or at least 4 "
                             f"B-spline control values, got {self.amplitude!r}")

    def _pieces(self):
        """The clamped cubic B-spline of the control values: its inner knots (uniform on
        [0, 1]) and its polynomial pieces [(x0, x1, coefficients from the cubic's)] on
        the knot intervals; None for a number."""
        beta = np.atleast_1d(np.asarray(self.amplitude, float))
        if beta.size == 1:
            return None
        from scipy.interpolate import BSpline, PPoly
        inner = np.linspace(0.0, 1.0, beta.size - 2)
        knots = np.concatenate([[0.0] * 3, inner, [1.0] * 3])
        pieces = PPoly.from_spline(BSpline(knots, beta, 3))
        return inner, [(x0, x1, pieces.c[:, i]) for i, (x0, x1) in
                       enumerate(zip(pieces.x[:-1], pieces.x[1:])) if x1 > x0]

    def coefficients(self) -> np.ndarray:
        """beta's numbers: the amplitude (shape ()), or the spline pieces' polynomial
        coefficients (4, pieces), highest power first."""
        spline = self._pieces()
        if spline is None:
            return np.asarray(float(np.atleast_1d(self.amplitude)[0]))
        return np.stack([c for _, _, c in spline[1]], axis=1)

    def profile(self, sigma, coefficients=None):
        """beta(sigma) (sigma a number, numpy array or UFL expression, 0 <= sigma <= 1 the
        fraction of the length from the origin): the number, or the cubic B-spline's
        polynomial pieces on its knot intervals.  ``coefficients``: a UFL expression of
        the shape of ``coefficients()`` (a model's Constant) in place of the numbers."""
        spline = self._pieces()
        if spline is None:
            beta = float(np.atleast_1d(self.amplitude)[0])
            return (beta if coefficients is None else coefficients) + 0.0 * sigma
        inner, breaks = spline
        if coefficients is not None:
            breaks = [(x0, x1, [coefficients[j, i] for j in range(4)])
                      for i, (x0, x1, _) in enumerate(breaks)]

        def poly(c, x):
            out = 0.0 * x + _number(c[0])
            for ck in c[1:]:
                out = out * x + _number(ck)
            return out
        if not isinstance(sigma, ufl.core.expr.Expr):
            sigma = np.asarray(sigma, float)
            k = np.clip(np.searchsorted(inner, sigma, side="right") - 1, 0, len(breaks) - 1)
            return np.choose(k, [poly(c, sigma - x0) for x0, _, c in breaks])
        out = poly(breaks[-1][2], sigma - breaks[-1][0])
        for x0, x1, c in reversed(breaks[:-1]):
            out = ufl.conditional(ufl.lt(sigma, x1), poly(c, sigma - x0), out)
        return out

    def moment(self, s, t: float, length: float) -> np.ndarray:
        """M(s, t) as numbers (s an array of arc lengths): (len(s), 3)."""
        s = np.asarray(s, float)
        sigma = s if self.origin == "start" else length - s
        ramp = min(1.0, t / self.ramp) if self.ramp > 0 else 1.0
        size = ramp * self.profile(sigma / length) * np.sin(
            2 * np.pi * (t / self.period - sigma / self.wave_length) + self.phase)
        return np.outer(size, self.unit())

    def unit(self) -> np.ndarray:
        """The axis made a unit vector."""
        return np.asarray(self.axis, float) / np.linalg.norm(self.axis)

    def loads(self, length: float) -> list:
        """The two DistributedLoads of kind "moment" whose sum is M (class docstring): their
        values WaveProfiles, their histories ramp(t) sin(w t) and ramp(t) cos(w t)."""
        self.check()
        w, ramp = 2 * np.pi / self.period, self.ramp

        def in_time(trig):
            def history(t):
                t = np.asarray(t, float)
                return (np.minimum(1.0, t / ramp) if ramp > 0 else 1.0) * trig(w * t)
            return load_histories.from_callable(history)
        return [DistributedLoad("moment", WaveProfile(self, length, "cos", 1.0),
                                in_time(np.sin), self.follower),
                DistributedLoad("moment", WaveProfile(self, length, "sin", -1.0),
                                in_time(np.cos), self.follower)]


def _number(c):
    """A polynomial coefficient: a float, or as it is (a UFL expression)."""
    return c if isinstance(c, ufl.core.expr.Expr) else float(c)


@dataclass(frozen=True)
class WaveProfile:
    """One of a TravellingWave's two profiles in s (the rod's own arc length):

        sign beta(sigma / L) trig(k sigma - phase) axis,    k = 2 pi / wave_length,

    callable at numbers (the force scale, force_scale.py).  In a model its numbers are
    fem.Constants (``constants``, made by external_forces.load_data; ``expression``), so
    that its kernels depend only on ``structure()`` (rod/structure.py): two muscles of
    other amplitudes, wave lengths, phases or rod lengths share compiled kernels."""

    wave: TravellingWave
    length: float
    trig: str                         # "cos" or "sin"
    sign: float

    def __call__(self, s):
        return self._components(s, {**self._numbers(), "beta": None})

    def structure(self) -> str:
        """What the compiled kernels depend on: the trigonometric function, sign, origin,
        the spline's number of control values (its knots), the unit axis, follower."""
        return (f"WaveProfile({self.trig},{self.sign!r},{self.wave.origin},"
                f"{np.atleast_1d(self.wave.amplitude).size},{self.wave.unit().tolist()!r},"
                f"{self.wave.follower!r})")

    def _numbers(self) -> dict:
        """beta's coefficients, the wave number k, the phase, L."""
        return {"beta": self.wave.coefficients(),
                "wave_number": 2 * np.pi / self.wave.wave_length,
                "phase": float(self.wave.phase), "length": float(self.length)}

    def constants(self, mesh) -> dict:
        """Its numbers as Constants on ``mesh``."""
        return {name: fem.Constant(mesh, value) for name, value in self._numbers().items()}

    def expression(self, s, constants: dict):
        """The profile as UFL at the arc length ``s``, its numbers ``constants``."""
        return ufl.as_vector(self._components(s, constants))

    def _components(self, s, numbers: dict) -> list:
        """The profile's components at ``s`` with ``numbers`` (beta None: the wave's)."""
        sigma = s if self.wave.origin == "start" else numbers["length"] - s
        size = self.sign * self.wave.profile(sigma / numbers["length"], numbers["beta"]) \
            * getattr(ufl, self.trig)(numbers["wave_number"] * sigma - numbers["phase"])
        return [float(a) * size for a in self.wave.unit()]


def check_loads(end_loads, distributed_loads, point_loads=(), length: float = np.inf) -> None:
    for load in point_loads:
        if not (np.isfinite(load.s) and 0.0 <= load.s <= length):
            raise ValueError(f"PointLoad s must be on the rod, 0 <= s <= L = {length:g}, "
                             f"got {load.s!r}")
    for load in list(end_loads) + list(distributed_loads) + list(point_loads):
        kinds = ("force", "couple", "moment") if isinstance(load, DistributedLoad) else (
            "force", "couple")
        if load.kind not in kinds:
            raise ValueError(f"{type(load).__name__} kind must be one of {', '.join(kinds)}, "
                             f"got {load.kind!r}")
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
    made with the terms), a WaveProfile's numbers and, at a point, the cell size h and
    the point s_0."""

    rod: int
    load: object
    where: str                # "end", "distributed" or "point"
    amplitude: fem.Constant
    value: fem.Constant | None
    point: tuple = ()         # (h, s_0) of a point load
    profile: dict = field(default_factory=dict)     # WaveProfile.constants

    def constants(self) -> dict:
        named = {"amplitude": self.amplitude, "value": self.value,
                 **dict(zip(("h", "s0"), self.point)),
                 **{f"profile_{name}": const for name, const in self.profile.items()}}
        return {name: const for name, const in named.items() if const is not None}


def _load_value(data: LoadData, disc: Discretisation):
    """The load's vector (its Constant, or value(s) for a distributed profile, s the rod's
    own arc length; a WaveProfile's of its Constants)."""
    if isinstance(data.load.value, WaveProfile):
        return data.load.value.expression(disc.pieces.local_s(data.rod), data.profile)
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
        profile = (load.value.constants(disc.mesh) if isinstance(load.value, WaveProfile)
                   else {})
        data.append(LoadData(rod, load, where, amp, value, point, profile))
    return histories, data


def apply_loads(F: dict, unk: Unknowns, disc: Discretisation, loads: list[LoadData],
                curvature=None):
    """Subtracts each load's virtual work from its balance block (``loads``: load_data);
    returns the power of the loads (a UFL form, or 0).  ``curvature``: the sections'
    (u, u_t) (constitutive.SectionResponse), for active moments."""
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
        elif load.kind == "moment":         # as the sections' moment (internal_work): dx_r
            u, u_t = curvature
            M = val if load.follower else ufl.dot(ufl.transpose(rotation_matrix(q)), val)
            du = ufl.derivative(u, unk.f[unk.rotation], unk.t[unk.rotation])
            F[unk.rotation] -= ufl.inner(M, du) * disc.dx_r
            power += ufl.inner(M, u_t) * disc.dx_r
        else:
            F[unk.rotation] -= integral(balance.couple_work(val, q, dTheta, load.follower))
            power += integral(balance.couple_work(val, q, unk.W, load.follower))
    return power


def _fluid_force(C, unk: Unknowns, v):
    """The anisotropic drag's force per reference length (minus): |v| R Q C Q^T R^T V,
    C in the directors' frame turned onto the centre line and per current length: Q
    the least rotation taking e_3 to the unit strain v / |v| (v = R^T r_s, the section's
    shear and stretch: Q = I + K + K^2 / (1 + v_3 / |v|), K the cross product with
    e_3 x v / |v|), so that the force's axis R Q e_3 is the centre line's tangent
    r_s / |r_s| where v is taken (the cell's midpoint) and turns with the directors
    along the cell, and |v| = |r_s| the stretch.  For C = (c_n, c_n, c_t) it is
    |r_s| (c_n (I - t t^T) + c_t t t^T) V, t that axis: slender-body theory's force on
    the centre line whatever the shear; an unshearable, inextensible rod (v = e_3) has
    R C R^T V."""
    R = rotation_matrix(unk.q)
    stretch = ufl.sqrt(ufl.dot(v, v))
    k = ufl.as_vector((-v[1], v[0], 0.0)) / stretch           # e_3 x v / |v|
    K = ufl.as_matrix([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    RQ = ufl.dot(R, ufl.Identity(3) + K + ufl.dot(K, K) / (1.0 + v[2] / stretch))
    return stretch * ufl.dot(RQ, ufl.dot(C, ufl.dot(ufl.transpose(RQ), unk.V)))


def drag(F: dict, unk: Unknowns, c: dict, params: list, disc: Discretisation, v=None):
    """Linear drag in the displacement block: isotropic f = -c V (a scalar ``drag``) or
    anisotropic f = -|v| R Q C Q^T R^T V (a drag tensor C in the directors' frame
    turned onto the centre line, ``v`` the section's strain R^T r_s: _fluid_force;
    resistive-force or slender-body theory, sections.slender_body_drag); rotational
    damping, the couple
    per length -C W (material: ``rotational_drag``) or -C_s w (spatial, w = R W:
    ``spatial_rotational_drag``, i.e. C = R^T C_s R) in the rotation block; returns
    their dissipation c V.V + V.f + W.C W integrated (0 without any on every rod)."""
    dissipation = []
    if not all(is_zero(scalars(p)["drag"]) for p in params):
        F["displacement"] += c["drag"] * ufl.inner(unk.V, unk.t["displacement"]) * disc.dx
        dissipation.append(c["drag"] * ufl.inner(unk.V, unk.V) * disc.dx)
    if DRAG_TENSOR in c:
        f = _fluid_force(c[DRAG_TENSOR], unk, v)
        F["displacement"] += ufl.inner(f, unk.t["displacement"]) * disc.dx
        dissipation.append(ufl.inner(f, unk.V) * disc.dx)
    for name in DAMPING:
        if name in c:
            C = c[name]
            if name.startswith("spatial"):
                R = rotation_matrix(unk.q)
                C = ufl.dot(ufl.transpose(R), ufl.dot(C, R))
            F[unk.rotation] += ufl.inner(ufl.dot(C, unk.W), unk.dTheta) * disc.dx
            dissipation.append(ufl.inner(unk.W, ufl.dot(C, unk.W)) * disc.dx)
    return sum(dissipation[1:], dissipation[0]) if dissipation else 0
