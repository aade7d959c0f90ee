"""The size of a rod's forces at time t: the scale of Newton's absolute test.

Newton's absolute test |R| < snes_atol compares the residual's 2-norm, nodal forces (the
displacement block) and couples (the rotation block) in the scene's units, with a
number.  A fixed number is not unit-free: a DNA molecule in N and m (forces 1e-12 N), a
fibre in SI under 1e-9 N m, pass every step's first guess unchanged, a silently wrong
answer; a steel rod in pN and nm never meets it.  Without a given snes_atol (scene
``time.atol``) a rod's is checks.NEWTON_FORCE_TOL times

    S(t) = max(f, m / L) max(1, L),
    f = max(F*, F* |d(t)| / L, largest force load at t),
    m = max(F* L |theta(t)|, largest couple load at t),    F* = max |A| / L^2,

with L the longest rod's length, d and theta the prescribed end displacements and
rotation vectors, a distributed load counted with its rod's length (a weight: rho A g
L), and F* the force that bends a rod by a radian (A its largest bending or torsional
stiffness, over s and the rods).  In a change of units forces F -> a F and lengths L
-> b L this scales as the residual's largest rows do (couples f L where L > 1, forces
where L < 1), so a solve stops at the same point in any units.  F* is the floor: the
scale of the internal forces of a deformed rod without loads (free vibration, a rod
relaxing after its loads are removed, a load history through zero), at which Newton
stops within 1e-10 L of the configuration.
"""

from __future__ import annotations

import numpy as np

from .material import largest_entry


def _load_size(data, length: float) -> float:
    """A load's largest value (LoadData) over its rod of ``length`` (a distributed load
    times the length), for a history of 1; a profile value(s) that cannot be evaluated
    at floats (UFL only) counts 0 (F* stays the floor)."""
    load = data.load
    if callable(load.value):
        try:
            size = largest_entry(lambda s: np.linalg.norm(np.asarray(load.value(s), float)),
                                 length)
        except ValueError:
            return 0.0
    else:
        size = float(np.linalg.norm(np.asarray(load.value, float)))
    return size * length if data.where == "distributed" else size


class ForceScale:
    """S(t) of a model's rods (module docstring): ``rods`` (rods.Rod), their loads'
    LoadData (external_forces.load_data) and end supports (EndSupports)."""

    def __init__(self, rods, loads, supports):
        self.length = max(float(rod.params.length) for rod in rods)
        self.stiffness_force = max(largest_entry(rod.params.A, float(rod.params.length))
                                   / float(rod.params.length) ** 2 for rod in rods)
        self.loads = [(data.load.kind, _load_size(data, float(rods[data.rod].params.length)),
                       data.load.history) for data in loads]
        self.supports = supports

    def __call__(self, t: float) -> float:
        L, f_star = self.length, self.stiffness_force
        f, m = f_star, 0.0
        for kind, size, history in self.loads:
            value = size * abs(float(history(t)))
            if kind == "force":
                f = max(f, value)
            else:
                m = max(m, value)
        for supports in self.supports:
            for motion in supports.displacement.values():
                f = max(f, f_star * float(np.linalg.norm(motion(t))) / L)
            for motion in supports.rotation.values():
                m = max(m, f_star * L * float(np.linalg.norm(motion(t))))
        return max(f, m / L) * min(1.0, L)
