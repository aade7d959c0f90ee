"""Closed rods (rings): a rod whose end is welded to its own start.

    RodModel(params, n_cells, closed=True, excess_link=0.0, start="clamped" | "free")

(scene: ``geometry.closed = true``, ``geometry.excess_link``).  A closed rod starts as
the circle of circumference L (radius L/(2 pi)) in the (d1, d3) plane of its start,
bending towards d1 (``Arc(L/(2 pi))`` closed on itself), its sections turned about the
tangent by the angle phi(s) = (u_ref,3 + 2 pi excess_link / L) s: its natural twist
(the third reference curvature) and ``excess_link`` turns more.  Started planar
(writhe 0), its linking number beyond the natural one is excess_link, Lk = Tw + Wr,
and the weld keeps it: a twisted ring may writhe out of its plane but not untwist
(Michell's instability, docs/stability.md).  Its stress-free shape is its own
(straight by default: the ring is bent, M = EI/R).

The weld is the start's support: the rod's two end nodes are the same material point,

* ``start = "free"`` (a free ring, dynamic rods): the end node's displacement and
  rotation increments follow the start node's (fem/multipoint.NodeLink, as a rigid
  joint, rod/joints.py): x_L = x_0 + (0 - L) e_3 (the same point r = s e_3 + x) and
  theta_L = R_rel^T theta_0, R_rel = R(q(0))^T R(q(L)) of the ring at t = 0, the turn
  by phi(L) about d3; this keeps q(L) = q(0) R_rel exactly, no penalty;
* ``start = "clamped"`` (the weld point held, quasi-static or dynamic): both end nodes
  are held where the ring starts, the same point and frame up to R_rel; no link is
  needed.  Held at one point, a ring is as stable as the free ring less its rigid
  motions; of the free ring's zero modes one stays: an isotropic ring (A_1 = A_2,
  B_1 = B_2) that is straight when stress-free is a **mechanism**, turning rigidly about
  the weld's tangent with every section spinning back about its own tangent by the same
  angle (strains unchanged, the weld's frame too): the tangent stiffness's exact zero
  eigenvalue (tests/test_ring.py).  A quasi-static load with a moment about that
  tangent has no equilibrium near the start (the ring swings like a pendulum until the
  moment vanishes): ``check_mechanism`` refuses it.

A closed rod may be one of a system's rods (rod/system.RodSystem: it starts as its
ring where it is placed, ``closed_starts``; joints join it at any node but its weld,
located on that ring, ``initial_shape``).  Its end is free (the weld is its support),
its ends have no prescribed motion, slide, turn or spring, and its stress-free shape
has no corners; a quasi-static closed rod is clamped at its weld (a free ring is not
held against rigid motions); it starts as its ring (a starting state's position,
orientation, velocities apply; a ``shape`` is refused).  Every error names the key.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..checks import MAX_CELL_TURN
from ..theory.quaternions import CONJ, np_qmul, np_quaternion_from_rotation_vector, \
    np_rotation_matrix
from .linking import twist, writhe
from .placement import place, placed_shape
from .start import StartingState

WELD_SUPPORTS = ("clamped", "free")
# the scene key of each of check_closed's errors, by the message's first word
KEYS = {"closed": "geometry.closed", "excess_link": "geometry.excess_link",
        "start": "boundary.start", "end": "boundary.end",
        "end_displacement": "boundary.end_displacement",
        "end_rotation": "boundary.end_rotation", "end_slide": "boundary.end_slide",
        "end_springs": "boundary.end_spring", "end_turn": "boundary.end_turn",
        "reference_shape": "geometry.reference_shape"}


@dataclass(frozen=True)
class Ring:
    """The starting curve of a closed rod of length L and n cells: its nodes at the
    angles 2 pi s/L on the circle bending towards d1 whose inscribed n-gon has sides h =
    L/n (radius L/(2 n sin(pi/n)) -> L/(2 pi): unstretched cells), its sections turned
    about the tangent by ``twist`` s (twist: rad per length).  The nodal frames are
    those of the n-gon's symmetry, q_i = Z^i q_t T^i (Z the turn by 2 pi/n about the
    ring's axis, T the turn by twist h about d3), with q_t the small tilt of the start
    frame (0 untwisted; O(h^2 twist/R) otherwise) that puts d3 of every cell's midpoint
    (the geodesic between its nodes' frames: the 1-point rule's) along its chord: no
    shear in the cells (d3 at the nodes exactly tangent would leave a twisted cell a
    shear h^2 twist/(8 R), which B turns into large forces)."""

    twist: float

    def frames(self, s, length: float, n_cells: int):
        i = np.rint(np.asarray(s, float) * n_cells / length)
        angle, turn = 2.0 * np.pi / n_cells, self.twist * length / n_cells
        radius = (length / (2.0 * n_cells)) / np.sin(np.pi / n_cells)
        r = radius * np.stack([1.0 - np.cos(i * angle), 0.0 * i, np.sin(i * angle)], axis=1)
        tilt = _tilt(angle, turn) if turn else np.array([1.0, 0.0, 0.0, 0.0])
        Z = np_quaternion_from_rotation_vector(np.outer(i * angle, E2))
        T = np_quaternion_from_rotation_vector(np.outer(i * turn, E3))
        return r, np_qmul(np_qmul(Z, tilt), T)


E2, E3 = np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])


def _tilt(angle: float, turn: float) -> np.ndarray:
    """The start frame's tilt q_t (see Ring): Newton on the rotation vector (a, b, 0)
    for d3 of the geodesic midpoint of q_t and Z q_t T along the chord of the first
    cell, whose direction is (sin(angle/2), 0, cos(angle/2))."""
    chord = np.array([np.sin(angle / 2), 0.0, np.cos(angle / 2)])
    Z = np_quaternion_from_rotation_vector(angle * E2)
    T = np_quaternion_from_rotation_vector(turn * E3)

    def misfit(x):
        q = np_quaternion_from_rotation_vector(np.array([x[0], x[1], 0.0]))
        mid = q + np_qmul(np_qmul(Z, q), T)
        d3 = np_rotation_matrix(mid)[:, 2]
        return np.array([d3[1], np.cross(chord, d3)[1]])   # off the plane, in it

    x = np.zeros(2)
    for _ in range(50):
        f = misfit(x)
        if np.abs(f).max() < 1e-15:
            break
        step = 1e-7
        J = np.column_stack([(misfit(x + step * e) - f) / step for e in np.eye(2)])
        x = x - np.linalg.solve(J, f)
    return np_quaternion_from_rotation_vector(np.array([x[0], x[1], 0.0]))


def ring_of(rod) -> Ring:
    """The starting curve of a closed rod (rods.Rod): its natural twist and excess link."""
    length = float(rod.params.length)
    return Ring(float(np.asarray(rod.params.reference_curvature, float)[2])
                + 2.0 * np.pi * float(rod.excess_link) / length)


def check_closed(rods: list, dynamic: bool) -> None:
    """The rules of closed rods (see module): a ValueError naming the key (its first
    word: KEYS).  The rods: rods.Rod or any object with its attributes (the scene's
    rules: scenes/rules.py)."""
    for rod in rods:
        if not np.isfinite(float(rod.excess_link)):
            raise ValueError(f"excess_link must be a finite number of turns, got "
                             f"{rod.excess_link!r}")
        if not rod.closed:
            if rod.excess_link:
                raise ValueError("excess_link: the turns a ring is closed with; the rod is "
                                 "not closed (closed = true)")
            continue
        if rod.start not in WELD_SUPPORTS:
            raise ValueError(f"start: a closed rod's start is its weld: {' or '.join(WELD_SUPPORTS)}"
                             f" (the weld point held or a free ring), got {rod.start!r}")
        if rod.end != "free":
            raise ValueError(f"end: a closed rod's end is welded to its start, whose support "
                             f"it shares: leave end 'free', got {rod.end!r}")
        if not dynamic and rod.start != "clamped":
            raise ValueError("start: a quasi-static closed rod is clamped at its weld "
                             "(start = 'clamped'): a free ring is not held against rigid "
                             "motions, its equilibrium is not unique")
        for name in ("end_displacement", "end_rotation", "end_slide", "end_springs",
                     "end_turn"):
            if getattr(rod, name):
                raise ValueError(f"{name}: a closed rod's ends are its weld, held by "
                                 "start = 'clamped' or free; they take no motion, slide, "
                                 "turn or spring")
        twist = ring_of(rod).twist * float(rod.params.length)     # rad over the ring
        if np.hypot(2.0 * np.pi, twist) / rod.n_cells >= MAX_CELL_TURN:
            raise ValueError(f"excess_link: a ring of {rod.n_cells} cells closed with "
                             f"{twist / (2 * np.pi):.6g} turns of twist turns each cell's "
                             f"frame by {np.hypot(2 * np.pi, twist) / rod.n_cells:.3g} rad, "
                             f"more than the {MAX_CELL_TURN:g} rad two nodes represent: take "
                             f"n_cells > {np.hypot(2 * np.pi, twist) / MAX_CELL_TURN:.4g}")
        if rod.params.reference_shape is not None:
            raise ValueError("reference_shape: a closed rod's stress-free shape is that of "
                             "its reference strains (reference_curvature), not a curve")


# the generalized force of the mechanism below this fraction of its loads' size is 0
# (a symmetric pair of loads: round-off of the quadrature's sum, ~1e-16)
MECHANISM_ROUND_OFF = 1e-9
MECHANISM = "start: a quasi-static ring clamped at its weld"


def is_mechanism(rod) -> bool:
    """Whether a closed rod (rods.Rod) clamped at its weld is a mechanism (module
    docstring): quasi-static with its positions and rotations free of any rate (no
    drag), its section isotropic in bending and shear (constant A_1 = A_2, B_1 = B_2, no
    coupling of d1, d2 with the other axes) and straight and unsheared when
    stress-free.  A function of s, an energy psi or a rate is not proven one: False."""
    p = rod.params
    if not (rod.closed and rod.start == "clamped") or p.energy is not None or any(
            _rate(v) for v in (p.drag, p.rotational_drag, p.spatial_rotational_drag)):
        return False
    if any(callable(v) for v in (p.A, p.B, p.reference_curvature, p.reference_stretch)):
        return False
    straight = not np.any(np.asarray(p.reference_curvature, float)[:2]) and not np.any(
        np.asarray(p.reference_stretch, float)[:2])
    return straight and all(_isotropic(np.asarray(v, float)) for v in (p.A, p.B))


def _rate(value) -> bool:
    return value is not None and (callable(value) or bool(np.any(np.asarray(value, float))))


def _isotropic(tensor: np.ndarray) -> bool:
    """A stiffness (3 diagonal entries or 3x3) equal in d1 and d2, not coupling them."""
    t = np.diag(tensor) if tensor.ndim == 1 else tensor
    return t[0, 0] == t[1, 1] and not np.any(t[:2, :2] - t[0, 0] * np.eye(2)) \
        and not np.any(t[:2, 2]) and not np.any(t[2, :2])


def mechanism_forces(rod, points: int = 4096) -> dict:
    """The generalized force of each load of a closed rod along its mechanism (module
    docstring), by the load's history (the loads of one history add; each history's
    loads as a list of (name, Q, size)): the continuous ring of radius R = L/(2 pi) in
    its own frame, turned rigidly by d alpha about e_3 at the weld (dx = e_3 x r) with
    every section spinning back (the rotation e_3 - d_3 ), Q = F . (e_3 x r) for a force,
    C . (e_3 - d_3) for a couple; distributed loads by the midpoint rule on ``points``
    cells; an active moment ("moment" kind) on the material curvature's change
    E_3 x u.  A profile of s numpy cannot evaluate is left out.  ``size``: the load's
    largest Q (|F| 2R, 2 |C|, |m|/R per length): the scale of Q's round-off."""
    length = float(rod.params.length)
    radius = length / (2.0 * np.pi)
    spin = ring_of(rod).twist
    turn = np_rotation_matrix(np_quaternion_from_rotation_vector(
        np.asarray(rod.orientation, float)))
    groups: dict = {}

    def frames(s):
        phi = np.atleast_1d(np.asarray(s, float)) / radius
        c, si, ct, st = np.cos(phi), np.sin(phi), np.cos(spin * radius * phi), \
            np.sin(spin * radius * phi)
        r = radius * np.stack([1.0 - c, 0.0 * c, si], axis=1)
        d3 = np.stack([si, 0.0 * c, c], axis=1)
        e1 = np.stack([c, 0.0 * c, -si], axis=1)
        d1 = ct[:, None] * e1 + st[:, None] * E2
        return r, np.stack([d1, np.cross(d3, d1), d3], axis=2)   # columns d1, d2, d3

    def add(load, name, s, values, weights):
        r, R = frames(s)
        local = np.einsum("nij,nj->ni", R, values) if load.follower else values @ turn
        if load.kind == "force":
            work, size = np.cross(E3, r), 2 * radius
        elif load.kind == "couple":
            work, size = E3 - R[:, :, 2], 2.0
        else:                             # an active moment, material: E_3 x u
            local = np.einsum("nji,nj->ni", R, local)
            work, size = np.tile(np.cross(E3, [0.0, 1 / radius, spin]), (len(s), 1)), \
                np.hypot(1 / radius, spin)
        q = float(np.sum(weights * np.einsum("ni,ni->n", local, work)))
        bound = float(np.sum(weights * np.linalg.norm(values, axis=1))) * size
        groups.setdefault(id(load.history), []).append((name, q, bound))

    for k, load in enumerate(rod.point_loads):
        add(load, f"point_loads[{k}] ({load.kind} at s = {load.s:g})", [load.s],
            np.atleast_2d(np.asarray(load.value, float)), np.ones(1))
    s = (np.arange(points) + 0.5) * length / points
    for k, load in enumerate(rod.distributed_loads):
        try:
            values = np.stack(np.broadcast_arrays(
                *(load.value(s) if callable(load.value) else load.value), s)[:3], axis=1)
        except Exception:  # noqa: BLE001 - a UFL profile: not evaluated here
            continue
        add(load, f"distributed_loads[{k}] ({load.kind})", s, values.astype(float),
            np.full(points, length / points))
    return groups


def check_mechanism(rods: list, dynamic: bool) -> None:
    """A quasi-static clamped ring that is a mechanism (is_mechanism) under loads whose
    generalized force along it does not vanish (mechanism_forces; the loads of one
    history together): a ValueError naming the weld's support, its key ``start``, and
    what holds such a ring (Newton would diverge at the first load, DIVERGED_DTOL)."""
    if dynamic:
        return
    for rod in filter(is_mechanism, rods):
        for loads in mechanism_forces(rod).values():
            q, bound = sum(q for _, q, _ in loads), sum(b for *_, b in loads)
            if abs(q) <= MECHANISM_ROUND_OFF * bound:
                continue
            names = ", ".join(name for name, *_ in loads)
            raise ValueError(
                f"{MECHANISM} (start = 'clamped') with an isotropic section (A_1 = A_2, "
                f"B_1 = B_2) and a straight stress-free shape is a mechanism: it turns "
                f"freely about the weld's tangent, every section spinning back about its "
                f"own (the tangent stiffness's zero eigenvalue); {names} "
                f"{'has' if len(loads) == 1 else 'have'} a moment {q:.6g} about that "
                f"tangent, which no equilibrium near the start balances (the ring would "
                f"swing like a pendulum).  Hold it: drag (material.drag or "
                f"rotational_drag: the quasi-static ring then turns at a viscous rate to "
                f"its equilibrium), a section stiffer about d1 than about d2 (A_1 > A_2: "
                f"the ring bends about d2), a stress-free curvature (reference_curvature), "
                f"a dynamic run (material.density), or loads without a moment about the "
                f"weld's tangent")


def welded_ends(rod):
    """The rod as the model holds it: a clamped ring's end clamped too (its weld)."""
    return replace(rod, end=rod.start) if rod.closed and rod.start == "clamped" else rod


def weld_nodes(model) -> list[tuple[float, float]]:
    """(s of the start node, s of the end node) of each closed rod on the model's mesh:
    neighbours through the weld (pass-through check, segment contact)."""
    layout = model.layout
    return [(layout.starts[k], layout.starts[k] + layout.lengths[k])
            for k, rod in enumerate(model.rods) if rod.closed]


def weld_links(model) -> list:
    """The links of a free ring's weld (see module): the end node's displacement and
    rotation increments follow the start node's (fem/multipoint.NodeLink; imported here:
    the checks above, numpy only, serve ``dolfin-rod check`` without DOLFINx)."""
    from ..fem.multipoint import NodeLink
    blocks = model.names
    links = []
    for (s_a, s_b), rod in zip(weld_nodes(model), (r for r in model.rods if r.closed)):
        if rod.start != "free":
            continue
        q_a, q_b = ring_of(rod).frames(np.array([0.0, float(rod.params.length)]),
                                       float(rod.params.length), rod.n_cells)[1]
        relative = np_rotation_matrix(np_qmul(q_a * CONJ, q_b))
        links += [NodeLink(blocks.index("displacement"), s_a, s_b, tuple(map(tuple, np.eye(3)))),
                  NodeLink(blocks.index(model.unknowns.rotation), s_a, s_b,
                           tuple(map(tuple, relative.T)))]
    return links


def initial_shape(rod, s) -> tuple[np.ndarray, np.ndarray]:
    """(r, q) at a rod's own nodes' arc lengths s where it starts unless a starting
    state moves it (rods.Rod or placement.PlacedRod): a closed rod's ring, another rod's
    stress-free shape; placed (joint_points: a joint at a ring's node)."""
    if not getattr(rod, "closed", False):
        return placed_shape(rod, s)
    return place(rod, *ring_of(rod).frames(s, float(rod.params.length), rod.n_cells))


def closed_starts(rods, starts: dict | None) -> dict | None:
    """A system's starting states (rod/start.RodStarts' {rod name: StartingState}, or
    None) with each closed rod's its ring (closed_start); a ValueError naming
    ``start['<rod>'].shape`` if one gives a curve."""
    closed = [rod for rod in rods if rod.closed]
    if not closed:
        return starts
    starts = dict(starts or {})
    for rod in closed:
        try:
            starts[rod.name] = closed_start(rod, starts.get(rod.name))
        except ValueError as err:
            raise ValueError(f"start[{rod.name!r}]" + str(err).removeprefix("start")) from None
    return starts


def closed_start(rod, start):
    """The starting state of a closed rod (rod/start.StartingState or None): its ring,
    placed and moving as ``start`` says; a ValueError naming ``start.shape`` if it gives
    a curve."""
    if start is None:
        return StartingState(shape=ring_of(rod))
    if start.shape is not None:
        raise ValueError("start.shape: a closed rod starts as its ring (closed = true, "
                         "excess_link turns of twist); give no starting curve")
    return replace(start, shape=ring_of(rod))


def ring_linking(points, normals) -> tuple[float, float]:
    """(Tw, Wr) of a ring from its nodes 0..N (node N at node 0) and the normals (d1) at
    them (rod/linking.py): Wr of the closed polygon of nodes 0..N-1; Tw of the ribbon
    along the N segments and at every node, the weld's included, where node N's d1 is
    carried on into segment 0 (the weld's own turn R_rel, a fixed jump, left out).
    Tw + Wr is the twist the ring was closed with (Lk, Calugareanu-White): planar at
    the start (Wr = 0), Tw = its natural turns plus excess_link; kept as it writhes."""
    points, normals = np.asarray(points, float), np.asarray(normals, float)
    weld = twist(points[[-2, -1, 1]], normals[[-1, -1, -1]])   # the junction at the weld
    return twist(points, normals) + weld, writhe(points[:-1], closed=True)
