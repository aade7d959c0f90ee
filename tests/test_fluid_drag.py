"""Anisotropic (resistive-force, slender-body) fluid drag f = -R C R^T dr/dt with the
material tensor C = (c_n, c_n, c_t) (material.drag = [c_1, c_2, c_3], or
material.fluid_viscosity: sections.slender_body_drag), against closed forms of rigid
motions it drives: scenes/sedimenting_fibre.toml (a tilted fibre falling sideways, and,
with its overrides, pulled along and across its axis, and spun about its end); against
PyElastica's SlenderBodyTheory force; and the scene's errors.  The physics tests are
marked mpi: the same numbers on 2 ranks."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from dolfin_rod import run_scene
from dolfin_rod.rod.sections import slender_body_drag
from dolfin_rod.scenes import SceneError, load_scene
from quick_scenes import ROOT, quick_scene

comm = MPI.COMM_WORLD
FIBRE = ROOT / "scenes/sedimenting_fibre.toml"
FLAGELLA = ROOT / "scenes/continuum_flagella.toml"
QUIET = dict(outputs__animation=False, outputs__plots=False, outputs__fields=False,
             outputs__every=1)
# the scene's fibre: L, r, rho A, buoyant g, fluid viscosity
L, RADIUS, RHO_A, G, MU = 0.1, 1e-3, 2500.0 * math.pi * 1e-6, 4.86051, 1.41
C_N = 4 * math.pi * MU / math.log(L / RADIUS)
C_T = C_N / 2


def folder_of(tmp_path) -> Path:
    return Path(comm.bcast(str(tmp_path), root=0))


def run(folder: Path, t_end: float, dt: float, **overrides) -> np.ndarray:
    """The fibre's time series at every step up to t_end."""
    scene = quick_scene(FIBRE, time__dt=dt, time__t_end=t_end, **{**QUIET, **overrides})
    run_scene(scene, folder, quiet=True)
    return np.genfromtxt(folder / "timeseries.csv", delimiter=",", names=True)


def tip(rows) -> np.ndarray:
    """The tip's displacement since t = 0, one row per step."""
    x = np.column_stack([rows[f"tip_position_{c}"] for c in "xyz"])
    return x - x[0]


def rigid_fall(t: float, tangent, force) -> np.ndarray:
    """The displacement of a rigid fibre of axis ``tangent`` under a uniform force per
    length ``force`` from rest: rho A x'' = f - C x' splits into the parts along and across
    the axis, each x_i = (f_i / c_i) (t - tau_i (1 - exp(-t / tau_i))), tau_i = rho A / c_i
    (the uniform loads leave no stress: it neither bends nor turns)."""
    tangent, force = np.asarray(tangent, float), np.asarray(force, float)
    along = (force @ tangent) * tangent
    out = np.zeros(3)
    for f, c in ((along, C_T), (force - along, C_N)):
        tau = RHO_A / c
        out += f / c * (t - tau * (1 - math.exp(-t / tau)))
    return out


@pytest.mark.mpi
def test_sedimenting_fibre_drifts_at_the_closed_form_angle(tmp_path):
    """The scene as given (theta = 45 degrees): the tip's displacement is the closed
    form's up to generalized-alpha's O(dt^2) error, measured at t = 6 ms (three normal
    time constants, inside the transient): 3.0e-8, 7.5e-9 m at dt = 5e-4, 2.5e-4 (order
    2.00) of a displacement 4.9e-5 m.  At t = 50 ms it falls at the terminal velocity's
    angle phi = atan(1/3) = 18.43 degrees from the vertical to 1e-5 rad (the transient
    leaves exp(-t/tau_t) = 5e-6 of the velocity along the axis: measured 2.0e-6 rad), its
    last step the closed form's to 1e-6 (the O(dt^2) error of a step's difference)."""
    folder = folder_of(tmp_path)
    theta = math.pi / 4
    tangent, weight = (math.sin(theta), 0.0, math.cos(theta)), (0.0, 0.0, -RHO_A * G)
    errors = []
    for dt in (5e-4, 2.5e-4):
        rows = run(folder / str(dt), 0.006, dt)
        assert rows["time"][-1] == pytest.approx(0.006)
        errors.append(np.abs(tip(rows)[-1] - rigid_fall(0.006, tangent, weight)).max())
    assert errors[0] < 4e-8 and math.log2(errors[0] / errors[1]) > 1.9, errors
    rows = run(folder / "terminal", 0.05, 5e-4)
    v = np.diff(tip(rows)[-2:], axis=0)[0]
    assert abs(math.atan2(-v[0], -v[2]) - math.atan(1 / 3)) < 1e-5, v
    step = rigid_fall(0.05, tangent, weight) - rigid_fall(0.0495, tangent, weight)
    assert np.abs(v - step).max() < 1e-6 * np.abs(step).max(), (v, step)
    assert np.ptp(rows["tip_rotation_angle"]) < 1e-12      # it does not turn


@pytest.mark.mpi
@pytest.mark.parametrize("theta, c", [(0.0, C_T), (math.pi / 2, C_N)])
def test_fibre_pulled_along_and_across_its_axis_reaches_f_over_c(tmp_path, theta, c):
    """The drag given as the tensor [c_n, c_n, c_t] (material.drag), the fibre vertical
    (pulled along its axis by its weight: c = c_t) or horizontal (across it: c_n): after
    twelve of the slower time constant its velocity is w / c to 1e-5 (exp(-12.25) =
    4.8e-6 of the transient left along the axis: measured 5.0e-6; across 2e-11), its
    displacement the closed form's to the O(dt^2) error: < 1e-8 m (measured 3.8e-9 m of
    9.1e-4 and 4.8e-4 m at dt = 5e-4)."""
    folder = folder_of(tmp_path)
    rows = run(folder / "pull", 0.05, 5e-4, material__fluid_viscosity=None,
               material__drag=[C_N, C_N, C_T], initial__orientation=[0.0, theta, 0.0])
    x, dt = tip(rows), rows["time"][-1] - rows["time"][-2]
    assert -(x[-1, 2] - x[-2, 2]) / dt == pytest.approx(RHO_A * G / c, rel=1e-5)
    tangent = (math.sin(theta), 0.0, math.cos(theta))
    assert np.abs(x[-1] - rigid_fall(0.05, tangent, (0.0, 0.0, -RHO_A * G))).max() < 1e-8


@pytest.mark.mpi
def test_fibre_spun_about_its_end_feels_the_drag_torque(tmp_path):
    """Pinned at s = 0 and turned about e_2 by a couple M h(t) there (h a smooth step over
    D = 10 ms: a sudden couple rings the fibre's bending), the fibre sweeps the fluid at
    v = omega s across its axis: the drag's torque is int_0^L c_n omega s^2 ds = c_n omega
    L^3 / 3.  A rigid fibre: I theta'' + (c_n L^3 / 3) theta' = M h, I = rho A L^3 / 3 +
    rho I_11 L, turns at omega = 3 M / (c_n L^3) = 1 rad/s (M = c_n L^3 / 3) with the
    angle omega (t - D / 2 - tau) after the start, tau = 3 I / (c_n L^3) = 2.0 ms.  The
    chord's angle at t = 30-40 ms: its rate 1 rad/s to 1e-5 (the start's transient
    exp(-(t - D) / tau) is 5e-5 at 30 ms: measured 1.3e-6 over the window) and its
    offset the closed form's to 1e-4 rad: the drag bends the fibre, a lag of 8.3e-5 rad
    (8e-6 at 10 E: the elastic lag, not the drag's torque or the time step, measured the
    same at dt = 2.5e-4)."""
    folder = folder_of(tmp_path)
    couple, duration = C_N * L**3 / 3, 0.01
    rows = run(folder / "spin", 0.04, 5e-4, boundary__start="pinned",
               loads__gravity=[0.0, 0.0, 0.0], initial__orientation=[0.0, 0.0, 0.0],
               loads__start_couple={"type": "smooth_step", "duration": duration,
                                    "value": [0.0, couple, 0.0]})
    angle = np.arctan2(rows["tip_position_x"], rows["tip_position_z"])
    last = rows["time"] >= 0.03 - 1e-9
    rate, offset = np.polyfit(rows["time"][last], angle[last], 1)
    inertia = RHO_A * L**3 / 3 + 2500.0 * math.pi * RADIUS**4 / 4 * L
    tau = 3 * inertia / (C_N * L**3)
    assert rate == pytest.approx(1.0, abs=1e-5)
    assert offset == pytest.approx(-(duration / 2 + tau), abs=1e-4)


@pytest.mark.mpi
def test_the_flagellum_s_power_balance_closes_with_rotation_vectors(tmp_path):
    """scenes/continuum_flagella.toml (50 cells) for 40 ms (in the muscle's ramp) on
    rotation vectors: the muscle's power int M . u_t ds is in load_power (it was 0: a
    hyperelastic rod's rotation vectors had no strain rates, and the run stopped at
    t = 0.05 s as "diverged", its stored energy 1000 times what the loads had supplied),
    so that the power balance closes: the residual d/dt(K + Psi) + D - P after the first
    step, relative to the largest P, is 2.7e-3, 8.3e-4 at dt = 2e-3, 1e-3 (order 1.7;
    asserted: < 4e-3 and a ratio > 2.5)."""
    folder = folder_of(tmp_path)
    errors = []
    for dt in (2e-3, 1e-3):
        scene = quick_scene(FLAGELLA, time__dt=dt, time__t_end=0.04,
                            geometry__rotations="rotation_vector", **QUIET)
        run_scene(scene, folder / str(dt), quiet=True)
        rows = np.genfromtxt(folder / str(dt) / "timeseries.csv", delimiter=",", names=True)
        power = rows["load_power"][2:]
        assert np.all(power > 0)
        errors.append(np.max(np.abs(rows["power_residual"][2:])) / power.max())
    assert errors[0] < 4e-3 and errors[0] / errors[1] > 2.5, errors


def test_slender_body_drag_is_pyelastica_slender_body_theory():
    """PyElastica's slender_body_forces (its SlenderBodyTheory, Gazzola et al. 2018 eq.
    4.13) on straight elements of a rod along d_3 = (sin a, 0, cos a) moving at a uniform
    velocity v: its force per element length is -R C R^T v with C = slender_body_drag's
    (c_n, c_n, c_t), to round-off (1e-12)."""
    interaction = pytest.importorskip("elastica.interaction")
    a, n = 0.3, 10
    d3 = np.array([math.sin(a), 0.0, math.cos(a)])
    R = np.array([[math.cos(a), 0.0, math.sin(a)], [0.0, 1.0, 0.0],
                  [-math.sin(a), 0.0, math.cos(a)]])        # d_3 = R e_3
    v = np.array([0.3, -0.7, 1.1])
    lengths = np.full(n, L / n)
    forces = interaction.slender_body_forces(
        np.tile(d3[:, None], n), np.tile(v[:, None], n + 1), MU, lengths,
        np.full(n, RADIUS), np.full(n + 1, 1.0))
    C = np.diag(slender_body_drag(MU, L, RADIUS))
    np.testing.assert_allclose(forces / lengths, np.tile((-R @ C @ R.T @ v)[:, None], n),
                               rtol=1e-12)


@pytest.mark.parametrize("change, key", [
    ({"material.drag": [1.0, -1.0, 1.0], "material.fluid_viscosity": None}, "material.drag"),
    ({"material.drag": [[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
      "material.fluid_viscosity": None}, "material.drag"),
    ({"material.drag": [1.0, 1.0, 0.5]}, "material.drag"),
    ({"material.fluid_viscosity": -1.0}, "material.fluid_viscosity"),
    ({"section.shape": "rectangle", "section.radius": None, "section.sides": [1e-3, 1e-3]},
     "material.fluid_viscosity"),
    ({"geometry.length": 0.002}, "material.fluid_viscosity"),
])
def test_bad_fluid_drag_names_the_key(change, key):
    with pytest.raises(SceneError) as info:
        load_scene(FIBRE, change)
    assert info.value.key == key, str(info.value)


PYELASTICA_FLAGELLUM = 0.0134305   # m/s over [2 T, 4 T]: benchmarks/flagella_peer.py
                                   # --quick, 50 elements, dt = 5e-5 (1e-4: 0.0134165)


@pytest.mark.slow
@pytest.mark.mpi
def test_the_continuum_flagellum_swims_at_pyelastica_speed(tmp_path):
    """scenes/continuum_flagella.toml for 4 periods at dt = 4e-3: its centre of mass's
    average forward speed over [2 T, 4 T] against PyElastica's run of its own example
    (same parameters, window).  Measured 0.013538 m/s, 0.80 % above; dolfin_rod's moves
    by 5e-4 on 100 cells and 8e-6 at dt = 2e-3, PyElastica's by 0.4 % on 100 elements
    (0.013373 m/s, falling: its muscle torques on the elements' ends are O(h)).
    Asserted to 1.5 %, the difference and twice PyElastica's own resolution change."""
    from dolfin_rod import read_pvd
    folder = folder_of(tmp_path)
    scene = quick_scene(FLAGELLA, time__dt=4e-3, time__t_end=4.01, outputs__every=5,
                        outputs__animation=False, outputs__plots=False)
    run_scene(scene, folder / "swim", quiet=True)
    frames = read_pvd(folder / "swim" / "rod.pvd")
    times = np.array([frame["time"] for frame in frames])
    centre_z = [np.trapezoid(frame["points"][:, 2]) / (len(frame["points"]) - 1)
             for frame in frames]                      # the centre of mass's z (P1, exact)
    a, b = (int(np.argmin(np.abs(times - t))) for t in (2.0, 4.0))
    forward = (centre_z[b] - centre_z[a]) / (times[b] - times[a])
    assert forward == pytest.approx(PYELASTICA_FLAGELLUM, rel=1.5e-2)
