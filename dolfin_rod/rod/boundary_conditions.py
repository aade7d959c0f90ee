"""Supports and prescribed motions of the rod's ends, and the reactions there.

ends: (left, right), each "clamped" (x and q fixed), "pinned" (x fixed) or "free".
end_displacement, end_rotation: {end: history t -> 3-vector}: a prescribed motion of an
end (displacement from its initial position; rotation vector superposed on its initial
rotation); the end's velocities (dynamic rods) follow from loads.rate (the history's own
derivative if it has one).  A dynamic rod cannot follow a jump of an end: a motion that
is not 0 at t = 0 (the rod starts at rest in its initial configuration) or that declares
jumps (``jumps``, as loads.PiecewiseSmoothLoad) is refused, as TorsionModel refuses a
step in the end rotation; other jumps of an arbitrary callable cannot be detected.

Reactions at a supported end: the residual tested with a unit virtual translation or
spatial rotation of that end node only (the hat function of the node).
"""

from __future__ import annotations

import dolfinx.fem as fem
import numpy as np
import ufl

from .. import loads
from ..model_base import ENDS, end_coordinate
from ..rotations import np_qmul, np_quaternion_from_rotation_vector, qmul

END_TYPES = ("clamped", "pinned", "free")
_IDENTITY = np.array([1.0, 0, 0, 0])


def check_supports(ends, end_displacement, end_rotation, dynamic: bool = False) -> None:
    if len(ends) != 2 or any(e not in END_TYPES for e in ends):
        raise ValueError(f"ends must be two of {END_TYPES}, got {ends!r}")
    for name, motion in (("end_displacement", end_displacement),
                         ("end_rotation", end_rotation)):
        for end, history in (motion or {}).items():
            if end not in ENDS:
                raise ValueError(f"{name}: unknown end {end!r}")
            if dynamic and (np.any(np.asarray(history(0.0), float) != 0.0)
                            or any(size for _, size in getattr(history, "jumps", ()))):
                raise ValueError(f"{name}[{end!r}] jumps (at t = 0 it must be 0: the rod "
                                 "starts at rest), but rho_A > 0: a rod with inertia cannot "
                                 "follow a jump of its end; use a smooth_step or a ramp")


class EndSupports:
    """The Dirichlet conditions of both ends and their values at time t."""

    def __init__(self, model, ends, end_displacement, end_rotation):
        self.ends = tuple(ends)
        self.displacement = dict(end_displacement or {})
        self.rotation = dict(end_rotation or {})
        self.initial = {end: (np.zeros(3), _IDENTITY.copy()) for end in ENDS}  # (x, q)
        self.values: dict = {}
        spaces, mesh, L = model.unknowns.spaces, model.mesh, model.length
        self.motion_rates = {end: (fem.Constant(mesh, np.zeros(3)), fem.Constant(mesh, np.zeros(4)))
                             for end in ENDS if end in self.displacement or end in self.rotation}
        for end, kind in zip(ENDS, self.ends):
            blocks = []
            if kind in ("clamped", "pinned") or end in self.displacement:
                blocks += [("displacement", (3,)), ("velocity", (3,))]
            if kind == "clamped" or end in self.rotation:
                blocks += [("quaternion", (4,)), ("gauge_multiplier", ()),
                           ("angular_velocity", (3,))]
            for block, shape in blocks:
                if block in spaces:
                    const = fem.Constant(mesh, np.zeros(shape) if shape else 0.0)
                    self.values[(block, end)] = const
                    model.dirichlet(block, spaces[block], end, L, const)

    def prescribed(self, end: str, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(x, q) of an end at time t."""
        x0, q0 = self.initial[end]
        d = np.asarray(self.displacement[end](t), float) if end in self.displacement \
            else np.zeros(3)
        if end in self.rotation:
            qr = np_quaternion_from_rotation_vector(np.asarray(self.rotation[end](t), float))
            return x0 + d, np_qmul(qr, q0)
        return x0 + d, q0

    def set(self, t: float) -> None:
        """Values at time t, and (dynamic rods) the velocities V = x_t and
        W = 2 vec(conj(q) q_t)/|q|^2 of the prescribed motion."""
        for end in ENDS:
            xe, qe = self.prescribed(end, t)
            self._set(("displacement", end), xe)
            self._set(("quaternion", end), qe)
            if ("velocity", end) in self.values:
                self._set(("velocity", end), loads.rate(lambda s: self.prescribed(end, s)[0], t))
            if ("angular_velocity", end) in self.values:
                qdot = loads.rate(lambda s: self.prescribed(end, s)[1], t)
                conj = qe * np.array([1, -1, -1, -1])
                self._set(("angular_velocity", end), 2 * np_qmul(conj, qdot)[1:] / (qe @ qe))

    def _set(self, key, value) -> None:
        if key in self.values:
            self.values[key].value[:] = value

    def reaction_forms(self, F: dict, unk, length: float) -> dict:
        """reaction_force_{end}_{xyz}, reaction_couple_{end}_{xyz} at supported ends."""
        forms = {}
        q = unk.f["quaternion"]
        power = 0
        for end in ENDS:
            hat = fem.Function(unk.spaces["gauge_multiplier"])
            hat.interpolate(lambda X, e=end_coordinate(end, length):
                            np.isclose(X[0], e).astype(float))
            if end in self.motion_rates:
                power += self._power_form(F, unk, end, hat)
            for i, comp in enumerate("xyz"):
                e_i = ufl.unit_vector(i, 3)
                if ("displacement", end) in self.values:
                    forms[f"reaction_force_{end}_{comp}"] = ufl.replace(
                        F["displacement"], {unk.t["displacement"]: hat * e_i})
                if ("quaternion", end) in self.values:
                    dq = 0.5 * hat * qmul(ufl.as_vector((0.0, e_i[0], e_i[1], e_i[2])), q)
                    forms[f"reaction_couple_{end}_{comp}"] = ufl.replace(
                        F["quaternion"], {unk.t["quaternion"]: dq})
        if self.motion_rates:
            forms["reaction_power"] = power
        return forms

    def _power_form(self, F: dict, unk, end: str, hat):
        """The residual tested with the end node's velocity hat * (x_t, q_t): the power
        of the reactions there (discrete test functions: the nodal values x_t, q_t times
        the hat function)."""
        x_t, q_t = self.motion_rates[end]
        form = 0
        if ("displacement", end) in self.values:
            form += ufl.replace(F["displacement"], {unk.t["displacement"]: hat * x_t})
        if ("quaternion", end) in self.values:
            form += ufl.replace(F["quaternion"], {unk.t["quaternion"]: hat * q_t})
        return form

    def set_motion_rates(self, t: float) -> None:
        """x_t and q_t of the moving ends at t, for the reaction power."""
        for end, (x_t, q_t) in self.motion_rates.items():
            x_t.value[:] = loads.rate(lambda s: self.prescribed(end, s)[0], t)
            q_t.value[:] = loads.rate(lambda s: self.prescribed(end, s)[1], t)
