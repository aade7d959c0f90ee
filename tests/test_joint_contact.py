"""Segment contact in rod systems with joints (issue 26; rod/pair_contact.py through
fem/multipoint.ConstrainedSystem: residual P^T F, Jacobian P^T J P with the pairs'
entries, the pattern grown with new pairs; docs/contact.md).

References: a cantilever made of two rods rigidly joined is the same discrete rod as
one rod with the nodes of both (a rigid joint ties every dof of the joint's two nodes),
so resting on a crossing rod it takes the same contact force and deflection as the
single rod (whose force tests/test_pair_contact.py checks against superposition); the
supports' reactions balance the applied load (total vertical force 0); the joint's own
two segments, which touch at the joint, are neighbours, never a pair.
"""

from __future__ import annotations

import numpy as np
import pytest

from dolfin_rod import TimeStepper
from dolfin_rod.analysis.stability import LowestEigenvalues, StabilityMonitor
from dolfin_rod.rod import EndLoad, RodParameters
from dolfin_rod.rod.contact import ContactLaw
from dolfin_rod.rod.joint_points import Joint
from dolfin_rod.rod.rods import Rod
from dolfin_rod.rod.system import RodSystem

R, DELTA, EI, P, L, N, A = 0.01, 2e-3, 1.0, 0.05, 1.0, 8, 0.75
BEAM = RodParameters(length=L, A=(EI, EI, EI), B=(1e4, 1e4, 1e4))
PROP = RodParameters(length=1.0, A=(1e3,) * 3, B=(1e6,) * 3)   # L: the metric's length
ALONG_E1 = (0, np.pi / 2, 0)


def _prop() -> Rod:
    """The stiff clamped-clamped rod B along e_2 under x = A, its centre line 2 r + 1.5
    delta below the cantilever's (crossing it at B's s = 0.5 + 1/30: inside a segment)."""
    return Rod(PROP, 4, "clamped", end="clamped",
               position=(A, -0.5 - 1 / 30, -(2 * R + 1.5 * DELTA)),
               orientation=(-np.pi / 2, 0, 0), name="B")


def _load():
    return [EndLoad("force", (0, 0, -P), lambda t: t)]


def _system(joined: bool) -> RodSystem:
    """The cantilever (EI = 1, 8 cells, clamped at 0, tip load -P e_3 ramped over t in
    [0, 1]) as one rod, or as two rods of 4 cells rigidly joined at x = L/2; on B."""
    if joined:
        half = RodParameters(**{**BEAM.__dict__, "length": L / 2})
        rods = [Rod(half, N // 2, "clamped", end="free", orientation=ALONG_E1, name="A1"),
                Rod(half, N // 2, "free", _load(), end="free", position=(L / 2, 0, 0),
                    orientation=ALONG_E1, name="A2"), _prop()]
        joints = [Joint("rigid", ("A1", "A2"), (L / 2, 0, 0), name="knee")]
    else:
        rods = [Rod(BEAM, N, "clamped", _load(), orientation=ALONG_E1,
                    name="A"), _prop()]
        joints = []
    system = RodSystem(rods, joints, model="hyperelastic",
                       contact=ContactLaw(R, DELTA, 1e6, between_rods=True))
    system.set_initial_state()
    stepper = TimeStepper(system.problem, solver_options={"snes_rtol": 1e-12,
                                                          "snes_atol": 1e-14, "snes_stol": 1e-15})
    for k in range(4):
        stepper.run(k / 4, (k + 1) / 4, 1 / 4)
    return system


@pytest.mark.mpi
def test_jointed_cantilever_resting_on_a_rod():
    """Two rigidly joined halves = one rod: contact force (0.06792 = 1.36 P) and tip
    deflection equal to 1e-8 relative (Newton to 1e-12 and a step test at 1e-15: the
    two solve the same discrete equations; measured: all printed digits equal; with
    the default step test 1e-8 they differed by 4e-7); the vertical reactions of A's
    clamp and B's two clamps balance P to Newton's residual (every step stops by its
    step test at a residual of 2.6e-9..3.6e-9 N, measured: the round-off floor of the
    barrier's forces, far above snes_atol's 1e-14; the sum is off by 1.8e-9 N:
    asserted abs 1e-8 N = 2e-7 P); two pairs (A's node over B is shared by two segments), the same as the
    single rod's: the joint's own segments, touching at the joint, are no pair."""
    joined, single = _system(True), _system(False)
    dj, ds = joined.diagnostics(1.0), single.diagnostics(1.0)
    assert dj["contact_pairs"] == ds["contact_pairs"] == 2
    assert 0 < dj["min_pair_gap"] < DELTA
    assert dj["pair_contact_force"] == pytest.approx(ds["pair_contact_force"], rel=1e-8)
    assert dj["A2.tip_position_z"] == pytest.approx(ds["A.tip_position_z"], rel=1e-8)
    vertical = dj["A1.reaction_force_start_z"] + dj["B.reaction_force_start_z"] + \
        dj["B.reaction_force_end_z"]
    assert vertical == pytest.approx(P, abs=1e-8)


@pytest.mark.mpi
def test_stability_of_the_jointed_system_in_contact():
    """The tangent of the joined system (P^T K P with the pairs' Hessians) has the
    single rod's lowest eigenvalues (lumped metric P^T G P: the joint's two nodes carry
    h/2 each, as the single rod's interior node h; both systems' longest rod L = 1 sets
    the metric's rotation scale): 2.0695, 2.4596, 11.546, equal to 1e-12 (asserted
    1e-6: the two Newton solutions agree to 1e-9); the monitor counts no negative one."""
    joined, single = _system(True), _system(False)
    monitors = [StabilityMonitor(model, lowest=True) for model in (joined, single)]
    assert [monitor.check(1.0) for monitor in monitors] == [0, 0]
    lowest = [LowestEigenvalues(monitor.tangent)(1.0, 3) for monitor in monitors]
    assert np.allclose(lowest[0], lowest[1], rtol=1e-6), lowest
    assert min(lowest[0]) > 0
