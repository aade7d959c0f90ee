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

from pathlib import Path

import numpy as np
import pytest

from dolfin_rod import TimeStepper
from dolfin_rod.analysis.continuation import ArcLength
from dolfin_rod.fem.fe_model import NodeValues
from dolfin_rod.rod import EndLoad, RodModel, RodParameters

ROOT = Path(__file__).resolve().parents[1]
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


@pytest.mark.mpi
def test_snap_through_scene(tmp_path):
    """scenes/snap_through_arch.toml ([continuation] method = "arc_length"): the same
    path as the API's above (its limit loads against displacement control; the series'
    time is the load factor; the parabola through the steps around each turning point,
    of equal arc lengths: 0.405589 and -0.149688, 1.2e-5 and 1.8e-5 off; tolerance 1e-3),
    and the tangent's count is 1 on the branch between the limit points and 0 on the
    others (item 1)."""
    import dolfin_rod
    from mpi4py import MPI
    out = MPI.COMM_WORLD.bcast(str(tmp_path / "arch"))
    result = dolfin_rod.run(ROOT / "scenes" / "snap_through_arch.toml",
                            {"outputs.fields": False, "outputs.animation": False},
                            out=out, quiet=True)
    assert result.status == "completed"
    lam = np.array(result.series["time"])
    count = np.array(result.series["negative_eigenvalues"])
    top, bottom = turning_points(lam)
    steps = np.arange(len(lam), dtype=float)
    d_ref, F_ref = displacement_controlled()
    upper, lower = turning_points(F_ref)
    assert extremum(steps, lam, top) == pytest.approx(extremum(d_ref, F_ref, upper), abs=1e-3)
    assert extremum(steps, lam, bottom) == pytest.approx(extremum(d_ref, F_ref, lower),
                                                         abs=1e-3)
    assert np.all(count[:top] == 0) and np.all(count[top + 2:bottom] == 1) \
        and np.all(count[bottom + 2:] == 0), count


def test_a_continuation_parameter_that_is_not_a_load_is_refused(tmp_path, capsys):
    from dolfin_rod.cli import main
    scene = tmp_path / "arch.toml"
    scene.write_text((ROOT / "scenes" / "snap_through_arch.toml").read_text().replace(
        'parameter = "loads.start_force"', 'parameter = "material.stiffness"'))
    assert main(["check", str(scene)]) == 2
    err = capsys.readouterr().err
    assert "[continuation.parameter]: 'material.stiffness' is not a load of this scene: " \
           "name one of loads.start_force" in err, err
