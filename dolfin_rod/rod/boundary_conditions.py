"""Supports and prescribed motions of the rod's ends, and the reactions there.

ends: (start, end) at s = 0 and s = L, each "clamped" (x and q fixed), "pinned" (x
fixed) or "free".
end_displacement, end_rotation: {end: history t -> 3-vector}: a prescribed motion of an
end (displacement from its initial position; rotation vector superposed on its initial
rotation); the end's velocities (dynamic rods) follow from loads.rate (the history's own
derivative if it has one).  A dynamic rod cannot follow a jump of an end: a motion that
declares jumps after t = 0 (``jumps``, as loads.PiecewiseSmoothLoad) is refused, as
TorsionModel refuses a step in the end rotation; other jumps of an arbitrary callable
cannot be detected.  A displacement or rotation that is not 0 at t = 0 gives a
consistent start (rotation vectors): the rod at rest in equilibrium with its ends where
they are at t = 0 (integrators/lie_alpha.py, the start).

end_slide: {end: axis}: a clamped or pinned end that slides freely along a unit axis:
its position is held (or prescribed) across the axis only, its rotation as a clamped (or
pinned) end's; a force along the axis acts on it (a weight on a sliding clamp,
cosseratbench's twist experiment).

end_turn: {end: axis}: a clamped end that turns freely about a unit axis (spatial; a
hinge; with end_slide along the same axis a cylindrical joint): its rotation is held
about the other two axes only; a couple about the axis acts on it.  Its initial rotation
must turn the axis as its stress-free rotation R_sf does (R_0^T axis = R_sf^T axis: a
start may turn the end about the axis only).

A coordinate axis (+-e_i; for a turn, one its stress-free end frame keeps, R_sf^T axis =
axis) is held by Dirichlet conditions on the components across it (any rotation
unknowns).  Any other axis by a one-node link (fem/multipoint.NodeLine, ``linked_axes``;
rotation-vector unknowns): the end's displacement x = x_0 + a axis, its rotation
increment theta = psi R_sf^T axis (q_n c(theta) turns q_n about the spatial axis, exact),
with no motion prescribed across a linked slide axis.

end_springs: {end: EndSpring}: a compliant support, translational stiffness K (spatial
components, N/m) about the end's initial position and rotational stiffness K_r (material
components, N m/rad) about its initial rotation, with the energy
1/2 (x - x_0).K (x - x_0) + 2 vec(p).K_r vec(p), p = conj(q_0) q (unit): for a rotation by
phi about a principal axis k (1 - cos phi), linear for small rotations.  Translational
on an end whose position is free (or slides), rotational on one whose rotation is free.

Reactions at a supported end: the assembled residual at that end node, i.e. the residual
tested with a unit virtual translation or spatial rotation of the node only.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import dolfinx.fem as fem
import numpy as np
import ufl

from .. import loads
from ..checks import is_coordinate_axis, slide_axis_problem, spin_free, welded_spin_end
from ..fem import form_cache
from ..fem.fe_model import ENDS, NodeValues, compiled_near_nodes, nodal_residual
from ..fem.multipoint import NodeLine, NodePlane
from ..theory.rotations import (conj, np_qmul, np_quaternion_from_rotation_vector,
                                np_rotation_matrix, qmul, vec)
from .rotation_vector import np_inverse_cayley

END_TYPES = ("clamped", "pinned", "free")


@dataclass(frozen=True)
class EndSpring:
    """Stiffnesses of a compliant end support: ``translational`` K (a number: K I, or
    [k_x, k_y, k_z], spatial; N/m) and ``rotational`` K_r (a number or [k_1, k_2, k_3],
    material; N m/rad); see the module docstring."""

    translational: float | Sequence[float] = 0.0
    rotational: float | Sequence[float] = 0.0

    def stiffness(self, kind: str) -> np.ndarray:
        """The diagonal (3,) of the translational or rotational stiffness."""
        return np.broadcast_to(np.asarray(getattr(self, kind), float), (3,)).copy()
_IDENTITY = np.array([1.0, 0, 0, 0])
_CONJ = np.array([1.0, -1, -1, -1])


def check_supports(ends, end_displacement, end_rotation, dynamic: bool = False,
                   end_slide=None, end_springs=None, end_turn=None) -> None:
    if len(ends) != 2:
        raise ValueError(f"ends must be (start, end), got {ends!r}")
    for name, kind in zip(("start", "end"), ends):
        if kind not in END_TYPES:
            raise ValueError(f"{name} (the support at s = {'0' if name == 'start' else 'L'}) "
                             f"must be one of {END_TYPES}, got {kind!r}")
    for end, axis in (end_turn or {}).items():
        if end not in ENDS or dict(zip(ENDS, ends))[end] != "clamped":
            raise ValueError(f"end_turn[{end!r}]: only a clamped end turns in its support "
                             f"(ends = {ends!r})")
        problem = slide_axis_problem(axis)
        slide = (end_slide or {}).get(end)
        if problem or (slide is not None and np.any(np.asarray(slide) != np.asarray(axis))):
            raise ValueError(f"end_turn[{end!r}] " + (problem or "must equal end_slide's axis"))
        if end in (end_rotation or {}):
            raise ValueError(f"end_turn[{end!r}]: the end's rotation is prescribed "
                             "(end_rotation): it cannot also turn freely")
    for end, spring in (end_springs or {}).items():
        _check_spring(end, spring, dict(zip(ENDS, ends)).get(end), end_slide or {},
                      {**(end_displacement or {}), **(end_rotation or {})})
    for end, axis in (end_slide or {}).items():
        if end not in ENDS:
            raise ValueError(f"end_slide: unknown end {end!r}")
        if dict(zip(ENDS, ends))[end] == "free":
            raise ValueError(f"end_slide[{end!r}]: a free end has no support to slide in; "
                             "make it clamped or pinned")
        problem = slide_axis_problem(axis)
        if problem:
            raise ValueError(f"end_slide[{end!r}] {problem}")
        if end in (end_displacement or {}) and not is_coordinate_axis(axis):
            raise ValueError(f"end_displacement[{end!r}]: the end slides along "
                             f"{np.asarray(axis, float).tolist()} (end_slide), off the "
                             "coordinate axes: its motion across that axis cannot be "
                             "prescribed (only across +-e_i)")
    for name, motion in (("end_displacement", end_displacement),
                         ("end_rotation", end_rotation)):
        for end, history in (motion or {}).items():
            if end not in ENDS:
                raise ValueError(f"{name}: unknown end {end!r}")
            later = any(size for time, size in getattr(history, "jumps", ()) if time > 0)
            if dynamic and later:
                raise ValueError(f"{name}[{end!r}] jumps (after t = 0), but density > 0: a rod "
                                 "with inertia cannot follow a jump of its end; use a "
                                 "smooth_step or a ramp (a motion may start away from 0: "
                                 "the rod starts at rest in equilibrium with it)")


def _check_spring(end, spring, kind, slide: dict, moving) -> None:
    if end not in ENDS or not isinstance(spring, EndSpring):
        raise ValueError(f"end_springs: {{end: EndSpring}} with end 'start' or 'end', got "
                         f"{end!r}: {spring!r}")
    for part, held in (("translational", kind in ("clamped", "pinned") and end not in slide),
                       ("rotational", kind == "clamped")):
        k = np.asarray(getattr(spring, part), float)
        if k.shape not in ((), (3,)) or not np.all(np.isfinite(k)) or np.any(k < 0):
            raise ValueError(f"end_springs[{end!r}].{part} must be a number or 3 numbers "
                             f">= 0, got {getattr(spring, part)!r}")
        if np.any(k) and (held or end in moving):
            raise ValueError(f"end_springs[{end!r}].{part}: the end's "
                             f"{'position' if part == 'translational' else 'rotation'} is "
                             "held or prescribed there, the support takes the spring's place")


def linked_axes(end_slide, end_turn, end_frames: dict) -> dict:
    """{(block, end): axis in the block's components} of the supports a one-node link
    holds (module docstring): a slide along an axis off the coordinate axes
    ("displacement": the spatial axis), a turn about an axis that is not a coordinate
    axis kept by the end's stress-free rotation ``end_frames[end]`` (a quaternion)
    ("rotation_increment": the material axis R_sf^T axis)."""
    linked = {}
    for end, axis in (end_slide or {}).items():
        if not is_coordinate_axis(axis):
            linked["displacement", end] = np.asarray(axis, float)
    for end, axis in (end_turn or {}).items():
        a = np.asarray(axis, float)
        material = np_rotation_matrix(end_frames[end]).T @ a
        if not (is_coordinate_axis(a) and np.allclose(material, a, rtol=0, atol=1e-12)):
            linked["rotation_increment", end] = material
    return linked


def spin_normal(r: np.ndarray) -> np.ndarray:
    """n with n . q = (conj(r) q)_3: the material e_3 component of the rotation q
    relative to r (scalar first).  n . q = 0 is the rotation from r without twist about
    d3 (its swing-twist decomposition: conj(r) q = swing twist, (conj(r) q)_3 = swing_0
    twist_3, zero exactly when the twist is, for swings below pi): holding n . q at its
    start value removes the spin about d3 from the node's rotations, linearly."""
    return np.array([-r[3], r[2], -r[1], r[0]])


class HeldComponents:
    """The Dirichlet values of some components of a vector block at an end (a sliding
    end: the components across its axis), one scalar constant each."""

    def __init__(self, mesh, components):
        self.components = tuple(components)
        self.constants = [fem.Constant(mesh, 0.0) for _ in self.components]

    def assign(self, value) -> None:
        for i, const in zip(self.components, self.constants):
            const.value = value[i]


class EndSupports:
    """The Dirichlet conditions of both ends and their values at time t.

    Rotation vectors (discretisation.py): a clamped or rotated end holds theta_end =
    c^-1(conj(q_n,end) q_end(t)), with q_n,end = q_end(t_n) the end's rotation at the
    last accepted step t_n (``commit``; before the first, its initial rotation: a motion
    may jump at t0 in a quasi-static rod), so that q_n,end c(theta_end) = q_end(t).
    A free spin (spin_free: both ends pinned; ``spin_at``: the end of a rod of a welded
    system pinned at two ends, checks.welded_spin_end) is held about d3 at that end."""

    def __init__(self, model, ends, end_displacement, end_rotation, end_slide,
                 span: tuple[float, float], end_springs=None, end_turn=None,
                 end_frames: dict | None = None, spin_at: str | None = None):
        self.ends = tuple(ends)
        self.turn = {end: np.asarray(a, float) for end, a in (end_turn or {}).items()}
        self.linked = linked_axes(end_slide, end_turn, end_frames or {})
        if "velocity" in model.unknowns.spaces:      # quaternions: V = x_t on the line too
            self.linked.update({("velocity", end): axis for (block, end), axis
                                in list(self.linked.items()) if block == "displacement"})
        self.turn_material = {end: self.linked.get(("rotation_increment", end), a)
                              for end, a in self.turn.items()}  # R_0^T axis at the start
        self.springs = dict(end_springs or {})
        self.rest = {end: (fem.Constant(model.mesh, np.zeros(3)),
                           fem.Constant(model.mesh, _IDENTITY.copy())) for end in self.springs}
        self.displacement = dict(end_displacement or {})
        self.rotation = dict(end_rotation or {})
        self.slide = {end: np.asarray(a, float) for end, a in (end_slide or {}).items()}
        self.initial = {end: (np.zeros(3), _IDENTITY.copy()) for end in ENDS}  # (x, q)
        self.values: dict = {}
        self.block = model.unknowns.rotation
        self.committed_time = None      # rotation vectors: time of q_n (None: initial)
        self.fraction = 1.0            # of the motions at the time set (``scale``)
        self.committed_fraction = 1.0  # ... and at the time of q_n
        self.time_set = 0.0            # the time of the values last set (set)
        self._fixed_values_of: dict = {}      # end -> the initial (x, q) its values hold
        spaces, mesh = model.unknowns.spaces, model.mesh
        self.spaces = spaces
        self.s_ends = dict(zip(ENDS, span))     # the rod's ends on the mesh (layout.py)
        self._residual_forms: dict = {}
        for end, kind in zip(ENDS, self.ends):
            blocks = []
            if kind in ("clamped", "pinned") or end in self.displacement:
                blocks += [("displacement", (3,)), ("velocity", (3,))]
            if kind == "clamped" or end in self.rotation:
                blocks += [("quaternion", (4,)), ("gauge_multiplier", ()),
                           ("angular_velocity", (3,)), ("rotation_increment", (3,))]
            for block, shape in blocks:
                if block not in spaces:
                    continue
                components = self._held_components(end, block)
                if components is not None:
                    held = HeldComponents(mesh, components)
                    self.values[(block, end)] = held
                    for i, const in zip(held.components, held.constants):
                        model.dirichlet_at(block, spaces[block], self.s_ends[end], const,
                                           component=i)
                    continue
                const = fem.Constant(mesh, np.zeros(shape) if shape else 0.0)
                self.values[(block, end)] = const
                model.dirichlet_at(block, spaces[block], self.s_ends[end], const)
        self.spin_plane = None      # quaternions: the start's twist held (``links``)
        if not model.dynamic and spin_free(ends, self.rotation, self.turn, self.springs):
            spin_at = "start"
        self.spin_at = spin_at
        if spin_at is not None:
            if "rotation_increment" in spaces:      # quasi-static: a null mode
                model.dirichlet_at(self.block, spaces[self.block], self.s_ends[spin_at],
                                   fem.Constant(mesh, 0.0), component=2)
            else:
                self.spin_plane = spin_normal(np.asarray((end_frames or {}).get(
                    spin_at, _IDENTITY), float))
        unk = model.unknowns     # a turning end's rotation (reactions): nodal values
        self._rotations = unk.f["quaternion"] if unk.chart is None else unk.chart.q_n
        self._turned = {end: NodeValues(self._rotations.function_space, [self.s_ends[end]])
                        for end in self.turn}

    def _held_components(self, end: str, block: str):
        """The components a sliding or turning end holds of a block (None: all): those
        across the slide axis of the position and velocity, across the turning axis of
        the rotation increment, angular velocity and quaternion vector (its gauge
        multiplier: none)."""
        if (block, end) in self.linked:    # a one-node link holds it (``links``)
            return ()
        if end in self.slide and block in ("displacement", "velocity"):
            return np.flatnonzero(self.slide[end] == 0.0)
        if end not in self.turn:
            return None
        across = np.flatnonzero(self.turn[end] == 0.0)
        return {"rotation_increment": across, "angular_velocity": across,
                "quaternion": 1 + across, "gauge_multiplier": ()}.get(block)

    def links(self, blocks: list[str]) -> list[NodeLine]:
        """The one-node links of the supports on axes that are not coordinate axes
        (``linked_axes``), for a model whose blocks are ``blocks``."""
        lines = [NodeLine(blocks.index(block), self.s_ends[end], tuple(axis.tolist()))
                 for (block, end), axis in self.linked.items()]
        if self.spin_plane is None:
            return lines
        return lines + [NodePlane(blocks.index("quaternion"), self.s_ends[self.spin_at],
                                  tuple(self.spin_plane.tolist()))]

    def _end_rotation(self, end: str, t: float) -> np.ndarray:
        """The end's rotation now: prescribed, or of the state at a turning end."""
        if end not in self.turn:
            return self.prescribed(end, t)[1]
        q = self._turned[end](self._rotations.x.array)[0]
        return q / np.linalg.norm(q)

    def prescribed(self, end: str, t: float,
                   fraction: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(x, q) of an end at time t, its displacement and rotation vector scaled by
        ``fraction`` (default: the one ``scale`` set, 1 but in the start's path)."""
        x0, q0 = self.initial[end]
        f = self.fraction if fraction is None else fraction
        d = f * np.asarray(self.displacement[end](t), float) if end in self.displacement \
            else np.zeros(3)
        if end in self.rotation:
            qr = np_quaternion_from_rotation_vector(
                f * np.asarray(self.rotation[end](t), float))
            return x0 + d, np_qmul(qr, q0)
        return x0 + d, q0

    def largest_turn(self, t: float) -> float:
        """The largest angle |end_rotation(t)| of this rod's prescribed end rotations (0
        without any)."""
        return max((float(np.linalg.norm(np.asarray(rotation(t), float)))
                    for rotation in self.rotation.values()), default=0.0)

    def scale(self, fraction: float) -> None:
        """The prescribed motions' displacements and rotation vectors scaled by
        ``fraction`` from now on (the consistent start's path, integrators/lie_alpha.py:
        a turn of the ends beyond a quarter turn in committed parts)."""
        self.fraction = fraction

    def set(self, t: float) -> None:
        """Values at time t, and (dynamic quaternion rods) the velocities V = x_t and
        W = 2 vec(conj(q) q_t)/|q|^2 of the prescribed motion.  An end without a
        prescribed motion holds the same values at every t (rotation vectors: theta_end =
        c^-1(conj(q_0) q_0) = 0): they are set again only after its initial (x, q) changed
        (a new tuple, rod/initial_state.py), ~25 us of a step's ~400 at 8 cells."""
        for end in ENDS:
            fixed = end not in self.displacement and end not in self.rotation
            if fixed and self._fixed_values_of.get(end) is self.initial[end]:
                continue
            self._fixed_values_of[end] = self.initial[end] if fixed else None
            if end in self.turn and not np.allclose(
                    np_rotation_matrix(self.initial[end][1]).T @ self.turn[end],
                    self.turn_material[end], rtol=0, atol=1e-12):
                raise ValueError(f"end_turn[{end!r}]: the end's initial rotation turns the "
                                 f"axis {self.turn[end].tolist()} away: a turning end's "
                                 "initial frame must keep its axis (turn it about the "
                                 "axis only against its stress-free frame)")
            if end in self.rest:                 # a spring's rest state: the initial one
                for const, value in zip(self.rest[end], self.initial[end]):
                    const.value[:] = value
            xe, qe = self.prescribed(end, t)
            self._set(("displacement", end), xe)
            self._set(("quaternion", end), qe)
            if ("rotation_increment", end) in self.values:
                q_n = self.initial[end][1] if self.committed_time is None else \
                    self.prescribed(end, self.committed_time, self.committed_fraction)[1]
                self._set(("rotation_increment", end),
                          np_inverse_cayley(np_qmul(q_n * _CONJ, qe)))
            if ("velocity", end) in self.values:
                self._set(("velocity", end), loads.rate(lambda s: self.prescribed(end, s)[0], t))
            if ("angular_velocity", end) in self.values:
                self._set(("angular_velocity", end), self._angular_velocity(end, t))
        self.time_set = t

    def spring_energy(self, unk, ds, end_weight: dict, indicator):
        """The springs' energy (module docstring) as a form on the end points (``ds``
        weighted by ``end_weight[end]`` and the rod's ``indicator``), or 0."""
        energy = 0
        for end, spring in self.springs.items():
            x0, q0 = self.rest[end]
            e = unk.f["displacement"] - x0
            p = qmul(conj(q0), unk.q)
            K, K_r = (ufl.diag(ufl.as_vector(spring.stiffness(k).tolist()))
                      for k in ("translational", "rotational"))
            density = 0.5 * ufl.inner(e, ufl.dot(K, e)) + \
                2 * ufl.inner(vec(p), ufl.dot(K_r, vec(p))) / ufl.inner(p, p)
            energy += end_weight[end] * indicator * density * ds
        return energy

    def commit(self) -> None:
        """Rotation vectors: the accepted step ends at the time last set (chart.commit)."""
        self.committed_time, self.committed_fraction = self.time_set, self.fraction

    def _angular_velocity(self, end: str, t: float) -> np.ndarray:
        """Material angular velocity 2 vec(conj(q) q_t)/|q|^2 of a prescribed end."""
        qe = self.prescribed(end, t)[1]
        qdot = loads.rate(lambda s: self.prescribed(end, s)[1], t)
        return 2 * np_qmul(qe * _CONJ, qdot)[1:] / (qe @ qe)

    def _set(self, key, value) -> None:
        target = self.values.get(key)
        if isinstance(target, HeldComponents):
            target.assign(value)
        elif target is not None:
            target.value[:] = value

    def reactions(self, residual: dict, t: float, structure: str | None = None) -> dict:
        """reaction_force_{end}_{xyz}, reaction_couple_{end}_{xyz} at supported ends and the
        reaction_power of moving ends, at t (between steps): the assembled residual of
        the balance blocks at the end node (MPI-summed), i.e. the residual tested with a
        unit nodal translation, or a nodal spatial rotation e: delta q = (0, e) q_end / 2
        (quaternions) or delta theta = R(q_end)^T e (rotation vectors, theta = 0).
        ``structure``: the model's structure as data (its forms' kernels compiled once
        per structure), or None."""
        out, power, rotation_block = {}, 0.0, self.block
        ends = [e for e in ENDS if any((b, e) in self.values
                                       for b in ("displacement", rotation_block))]
        at_ends = {block: dict(zip(ends, nodal_residual(*self._compiled(residual, block, ends,
                                                                        structure))))
                   for block in ("displacement", rotation_block)
                   if any((block, e) in self.values for e in ends)}
        for end in ends:
            node = {block: values[end] for block, values in at_ends.items()
                    if (block, end) in self.values}
            if "displacement" in node:
                out.update(zip((f"reaction_force_{end}_{c}" for c in "xyz"),
                               node["displacement"].tolist()))
            if rotation_block in node:
                couple = spatial_rotations(rotation_block, self._end_rotation(end, t)) @ \
                    node[rotation_block]
                out.update(zip((f"reaction_couple_{end}_{c}" for c in "xyz"), couple.tolist()))
            if end in self.displacement or end in self.rotation:
                power += sum(node[b] @ v for b, v in self._motion_rates(end, t).items()
                             if b in node)
        if self.displacement or self.rotation:
            out["reaction_power"] = power
        return out

    def _compiled(self, residual: dict, block: str, ends, structure: str | None):
        """The block's residual form at the end nodes (its kernel compiled once per
        structure) and those nodes, made at the first diagnostics."""
        if block not in self._residual_forms:
            s_ends = [self.s_ends[e] for e in ends]
            key = form_cache.text_key(structure, "reaction", block, tuple(ends)) \
                if structure else None
            form = compiled_near_nodes(residual[block], self.spaces[block].mesh, s_ends, key)
            self._residual_forms[block] = (form, NodeValues(self.spaces[block], s_ends))
        return self._residual_forms[block]

    def _motion_rates(self, end: str, t: float) -> dict:
        """The nodal test values of a moving end's motion at t (between steps): x_t, and
        q_t (quaternions) or W (rotation vectors, theta = 0)."""
        # an end that only turns: x_t = 0, as the central difference of its fixed x gives
        x_t = loads.rate(lambda s: self.prescribed(end, s)[0], t) \
            if end in self.displacement else np.zeros(3)
        return {"displacement": x_t,
                self.block: (loads.rate(lambda s: self.prescribed(end, s)[1], t)
                             if self.block == "quaternion" else self._angular_velocity(end, t))}


_SPATIAL_AXES = np.hstack([np.zeros((3, 1)), np.eye(3)])     # (0, e_i) as quaternions


def spatial_rotations(block: str, q_end) -> np.ndarray:
    """Row i: the end node's test value of the spatial virtual rotation e_i (see
    ``reactions``): (0, e_i) q_end / 2 (quaternions), R(q_end)^T e_i (rotation vectors)."""
    if block == "quaternion":
        return 0.5 * np_qmul(_SPATIAL_AXES, q_end)
    return np_rotation_matrix(q_end)
