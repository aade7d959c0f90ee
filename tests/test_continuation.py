"""Arc-length continuation through limit points (issue 27 item 6,
dolfin_rod/analysis/continuation.py).

A shallow circular arch (radius R = 10, half-angle 0.1 rad: span 2.0, rise 0.05; EI = 1,
EA = GA = 1e4, pinned feet) under a central point load 2 F snaps through.  Half of it
by symmetry: s = 0 the crown, clamped (no turn) and sliding along the load's direction
-e_2, s = L = R 0.1 a pinned foot; 16 cells.  Its load F at the crown against the
crown's deflection d rises to a limit point, falls (the crown snaps: negative F holds
it), and rises again.  Reference, computed here independently of the arc length: the
same half-arch with the crown's deflection prescribed (displacement control, 200 steps
of 5e-4, the crown's reaction), where the curve is single-valued in d; its maximum and
minimum refined by the parabola through the three samples around them.  Measured
(16 cells): upper limit F = 0.404559 at d = 0.0300, lower -0.146969 at d = 0.0794; arc
length (ds = 0.01, psi = 1): 0.404558 and -0.146969 (parabolas through its points).
Tolerance 1e-3 F: the parabolas' error with the arc length's spacing at the limit
points (d steps of ~4e-3: (4e-3)^2 F''/8 ~ 2e-4 F).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dolfin_rod import TimeStepper
from dolfin_rod.analysis.continuation import ArcLength
from dolfin_rod.fem.fe_model import NodeValues
from dolfin_rod.rod import EndLoad, RodModel, RodParameters

RADIUS, HALF_ANGLE, CELLS = 10.0, 0.1, 16
ARCH = RodParameters(length=RADIUS * HALF_ANGLE, A=(1.0, 1.0, 1.0), B=(1e4, 1e4, 1e4),
                     reference_curvature=(1.0 / RADIUS, 0.0, 0.0))   # bends towards -e_2
DOWN = np.array([0.0, -1.0, 0.0])          # the load's direction at the crown


def crown_deflection(rod):
    crown = NodeValues(rod.f["displacement"].function_space, [0.0])
    return lambda: float(crown(rod.f["displacement"].x.array)[0] @ DOWN)


def extremum(x, y, k):
    """The vertex of the parabola through the points k - 1, k, k + 1."""
    a, b, _ = np.polyfit(x[k - 1:k + 2], y[k - 1:k + 2], 2)
    return float(np.polyval([a, b, _], -b / (2 * a)))


def turning_points(y) -> tuple[int, int]:
    """The first local maximum of y and the first local minimum after it."""
    rising = np.diff(y) > 0
    top = int(np.argmin(rising))                  # first step down
    return top, top + int(np.argmax(rising[top:]))


def displacement_controlled(steps: int = 200, d_max: float = 0.1):
    """(d, F) of the half-arch with the crown's deflection prescribed."""
    rod = RodModel(ARCH, n_cells=CELLS, model="hyperelastic", ends=("clamped", "pinned"),
                   end_displacement={"left": lambda t: d_max * t * DOWN})
    rod.set_initial_state()
    out = []

    def record(t, _):
        d = rod.diagnostics(t)
        out.append((d_max * t, np.array([d[f"reaction_force_left_{c}"] for c in "xyz"]) @ DOWN))

    TimeStepper(rod.problem).run(0.0, 1.0, 1.0 / steps, record)
    return np.array(out).T


def arc_length(ds: float = 0.01):
    """(lambda, d) of the arc-length path of the half-arch, F = lambda x 1."""
    rod = RodModel(ARCH, n_cells=CELLS, model="hyperelastic", ends=("clamped", "pinned"),
                   end_slide={"left": (0.0, 1.0, 0.0)},
                   end_loads=[EndLoad("force", tuple(DOWN), lambda t: t, end="left")])
    rod.set_initial_state()
    deflection = crown_deflection(rod)
    path = ArcLength(rod, ds=ds, observe=lambda lam: deflection())
    path.run(0.0, 1.0)
    return np.array(path.points).T


@pytest.mark.mpi
def test_shallow_arch_snaps_through_its_limit_points():
    d_ref, F_ref = displacement_controlled()
    upper, lower = turning_points(F_ref)
    lam, d = arc_length()
    top, bottom = turning_points(lam)
    assert extremum(d, lam, top) == pytest.approx(extremum(d_ref, F_ref, upper), abs=1e-4)
    assert extremum(d, lam, bottom) == pytest.approx(extremum(d_ref, F_ref, lower), abs=1e-4)
    assert np.all(np.diff(d) > 0)              # the crown goes down all along the path
    assert lam[-1] >= 1.0 and d[-1] > 0.11     # past the snap, on the far branch
