"""A node that would jump through a thin obstacle within one step is caught and the step
cut (issue 26; rod/contact.path_entry, ObstacleContact.check_state; docs/contact.md).

References: dense sampling of the straight paths (20001 points each) for the path test;
for a rod thrown at a thin cylinder with a step that carries it past the cylinder in
one step, the same run without the path check (its node jumps through: ends on the far
side) against the run with it (the node stays on its side, the rod bounces back).
"""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

from dolfin_rod import TimeStepper
from dolfin_rod.rod import RodModel, RodParameters, StartingState
from dolfin_rod.rod import contact
from dolfin_rod.rod.contact import (NP_OPS, ContactLaw, Obstacle, Pose, default_stiffness,
                                    path_entry, signed_distance)

THIN = Obstacle("cylinder", centre=(-0.05, 0.0, 0.1), axis=(0.0, 1.0, 0.0), radius=0.003,
                length=0.05)
BALL = Obstacle("sphere", centre=(0.3, -0.2, 0.1), radius=0.01)
RADIUS = 0.002


def test_path_entry_against_dense_sampling():
    """400 random straight paths of 0-0.4 m near a thin cylinder and a small sphere:
    path_entry says a node's path enters an obstacle (signed distance <= 0) exactly when
    20001 samples of it do (paths whose least sampled gap lies within 1e-6 m of 0 are left
    out: the samples' spacing, 2e-5 m, cannot decide them); both outcomes occur."""
    rng = np.random.default_rng(5)
    for obstacle in (THIN, BALL):
        pose = Pose(obstacle)
        centre = np.asarray(obstacle.centre)
        P0 = centre + rng.uniform(-0.2, 0.2, (400, 3))
        P1 = P0 + rng.uniform(-0.2, 0.2, (400, 3))
        tau = np.linspace(0.0, 1.0, 20001)[:, None]
        hits, counted = [], 0
        for p0, p1 in zip(P0, P1):
            least = np.min(signed_distance(pose, p0 + tau * (p1 - p0), NP_OPS))
            if abs(least) < 1e-6:
                continue
            counted += 1
            found = path_entry([pose], p0[None], p1[None])
            assert (found is not None) == (least <= 0), (p0, p1, least)
            hits.append(found is not None)
        assert counted > 390 and 0 < sum(hits) < len(hits)


def _thrown(dt: float, t_end: float):
    """A free rod (L = 0.2, 4 cells, r = 2 mm) along e_3 thrown at 1 m/s along -e_1
    towards the thin cylinder (radius 3 mm, axis e_2, 5 cm from it, at its middle
    node's height); the default barrier stiffness for dt.  Returns the middle node's x
    at every step and the steps' stats."""
    params = RodParameters(length=0.2, A=(1e-2,) * 3, B=(10.0,) * 3, density=1.0,
                           section_inertia=1e-6)
    law = ContactLaw(RADIUS, 5e-4, default_stiffness(1.0, (1e-2,) * 3, 0.2, 4, dt))
    rod = RodModel(params, 4, model="hyperelastic", start="free", end="free",
                   obstacles=[THIN], contact=law)
    rod.set_initial_state(start=StartingState(velocity=(-1.0, 0.0, 0.0)))
    stepper = TimeStepper(rod.problem)
    x = rod.unknowns.f["displacement"]
    middle = np.isclose(x.function_space.tabulate_dof_coordinates()[
        : x.function_space.dofmap.index_map.size_local, 0], 0.1)
    path = []
    for k in range(int(round(t_end / dt))):
        stepper.run(k * dt, (k + 1) * dt, dt)
        mine = x.x.array.reshape(-1, 3)[: len(middle)][middle, 0]
        path.append(MPI.COMM_WORLD.allreduce(float(mine.sum())))
    return np.array(path), stepper.stats


@pytest.mark.mpi
def test_a_node_does_not_jump_through_a_thin_obstacle(monkeypatch):
    """dt = 0.1 s carries the rod 0.1 m in a step, past the cylinder (6 mm thick + 2 r):
    without the path check the middle node jumps through it in the first step and ends
    at x = -0.4 (no contact force ever acts: every state's gap is > delta); with it the
    steps are cut (34 steps, 30 rejected), the node never gets past the cylinder's near
    side (x > -0.045 = -(0.05 - 0.003 - r); measured -0.0363 at t = 0.1) and the rod
    bounces back (x = 0.151 at t = 0.4)."""
    path, stats = _thrown(0.1, 0.4)
    assert stats.rejected > 0
    assert np.all(path > -0.045), path
    assert path[-1] > 0.0
    monkeypatch.setattr(contact, "path_entry", lambda *args: None)
    through, _ = _thrown(0.1, 0.4)
    assert through[0] < -0.053 and through[-1] == pytest.approx(-0.4, rel=1e-6)
