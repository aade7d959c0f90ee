"""The picture of docs/gallery.md's rod systems: runs scenes/frame.toml,
bent_frame.toml, double_pendulum.toml, tripod.toml and hinged_door.toml as a user runs
them and draws each against its reference (the small-load frame formula and the welded
frame against the bent one, the rigid double pendulum's ODE, the load the tripod's
clamps must carry, the rigid gate's ODE).

    ./rodenv python3 docs/gallery_systems.py    # ~1 min; docs/figures/gallery_systems.png
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from dolfin_rod import load_scene, read_vtx, run_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from rod_systems import door_angle, pendulum_angles, rigid_double_pendulum  # noqa: E402

FIGURES = ROOT / "docs" / "figures"
QUIET = {"outputs.animation": False, "outputs.plots": False, "outputs.progress": False}


def run(name: str) -> tuple[dict, list]:
    """The scene's time series (columns) and rod.bp steps."""
    folder = ROOT / "results" / "gallery" / name
    run_scene(load_scene(ROOT / "scenes" / f"{name}.toml", QUIET), folder, quiet=True,
              overwrite=True)
    rows = np.genfromtxt(folder / "timeseries.csv", delimiter=",", names=True,
                         deletechars="")
    return {k: rows[k] for k in rows.dtype.names}, read_vtx(folder / "rod.bp")


def shapes(ax, steps, every: int, plane=(0, 2)) -> None:
    """Every ``every``-th step's rods, coloured by time, projected on ``plane``."""
    colours = plt.cm.plasma(np.linspace(0.0, 0.85, len(steps[::every])))
    for colour, step in zip(colours, steps[::every]):
        for a, b in step["cells"]:
            ax.plot(*step["points"][[a, b]][:, plane].T, color=colour, lw=2)
    ax.set_aspect("equal")


def frame(ax_shape, ax_load) -> None:
    s, steps = run("frame")
    shapes(ax_shape, steps, 2)
    ax_shape.set(xlabel="x (m)", ylabel="z (m)", title="frame: column and beam welded")
    load = 1.0e4 * s["time"]
    drop = 2.0 - s["beam.tip_position_z"]
    EI, EA, kGA, L1, L2 = 4.0e4, 1.2e8, 2.05e7, 2.0, 1.5
    linear = load * (L2**3 / (3 * EI) + L2**2 * L1 / EI + L1 / EA + L2 / kGA)
    bent, _ = run("bent_frame")
    ax_load.plot(load / 1e3, drop, "o-", label="beam tip drop (m)")
    ax_load.plot(load / 1e3, 2.0 - bent["tip_position_z"], "x", ms=7,
                 label="bent_frame: one rod with a corner")
    ax_load.plot(load / 1e3, linear, "k--", label="small-load frame formula")
    ax_load.plot(load / 1e3, s["joint_knee_force_z"] / 1e4, "s-", ms=3,
                 label="knee force on the beam / 10 kN")
    ax_load.set(xlabel="tip load (kN)", title="frame: large deflection")
    ax_load.legend(fontsize=7)


def double_pendulum(ax) -> None:
    s, _ = run("double_pendulum")
    scene = load_scene(ROOT / "scenes" / "double_pendulum.toml")
    rho_A = scene.rods[0].scene["material"]["derived"]["density"]
    rho_I = scene.rods[0].scene["material"]["derived"]["section_inertia"][0]
    p = dict(g=9.81, rho_A=rho_A, rho_I=rho_I, l1=1.0, l2=0.7, angles=(0.6, 1.1))
    exact = rigid_double_pendulum(s["time"][-1], p).sol(s["time"])
    angles = np.array([pendulum_angles({k: s[k][i] for k in s}) for i in range(len(s["time"]))])
    for k, name in enumerate(("upper", "lower")):
        ax.plot(s["time"], angles[:, k], lw=2, label=f"{name} rod (ball joint)")
        ax.plot(s["time"], exact[k], "k--", lw=0.8)
    ax.plot([], [], "k--", lw=0.8, label="rigid double pendulum ODE")
    ax.set(xlabel="t (s)", ylabel="angle from the vertical (rad)",
           title=f"double pendulum: max |error| {np.abs(angles.T - exact[:2]).max():.1e} rad")
    ax.legend(fontsize=7)


def tripod(ax) -> None:
    s, steps = run("tripod")
    start, end = steps[0], steps[-1]
    moved = np.abs(end["points"] - start["points"]).max()
    magnify = float(f"{0.1 / moved:.0e}")           # the largest displacement ~0.1 m
    for colour, step, factor in (("0.6", start, 0.0), ("C0", end, magnify)):
        points = start["points"] + factor * (step["points"] - start["points"])
        for a, b in step["cells"]:
            ax.plot(*points[[a, b]].T, color=colour, lw=2)
    total = sum(np.array([s[f"leg{i}.reaction_force_start_{c}"][-1] for c in "xyz"])
                for i in (1, 2, 3))
    ax.view_init(elev=15, azim=-20)
    ax.set_box_aspect((0.75, 0.86, 1.0))
    ax.set(xlabel="x (m)", ylabel="y (m)", zlabel="z (m)",
           title=f"tripod (grey: unloaded; blue: displacement x {magnify:g})\nclamps "
                 f"carry {(-total).round(3).tolist()} N of [200, 0, -2000] N")


def gate(ax_top, ax_angle) -> None:
    s, steps = run("hinged_door")
    shapes(ax_top, steps, 6, plane=(0, 1))
    ax_top.set(xlabel="x (m)", ylabel="y (m)", title="gate on a hinge about e_3, from above")
    gate_scene = load_scene(ROOT / "scenes" / "hinged_door.toml").rods[1].scene
    derived = gate_scene["material"]["derived"]
    p = dict(rho_A=derived["density"], rho_I=derived["section_inertia"][0], width=1.2,
             push=2.0)
    angle = np.arctan2(s["gate.tip_position_y"], s["gate.tip_position_x"])
    exact = door_angle(s["time"][-1], p).sol(s["time"])[0]
    ax_angle.plot(s["time"], angle, lw=2, label="gate's angle about the hinge (rad)")
    ax_angle.plot(s["time"], exact, "k--", lw=0.8, label="rigid gate: I phi'' = F L cos phi")
    ax_angle.plot(s["time"], 100 * (1.0 - s["gate.tip_position_z"]), lw=1,
                  label="tip's sag x 100 (m): held up by the hinge")
    ax_angle.set(xlabel="t (s)", title=f"hinged gate: max |error| "
                                       f"{np.abs(angle - exact).max():.1e} rad")
    ax_angle.legend(fontsize=7)


def main():
    fig = plt.figure(figsize=(15, 8.4))
    ax = [fig.add_subplot(2, 3, k + 1, **({"projection": "3d"} if k == 3 else {}))
          for k in range(6)]
    frame(ax[0], ax[1])
    double_pendulum(ax[2])
    tripod(ax[3])
    gate(ax[4], ax[5])
    fig.tight_layout()
    FIGURES.mkdir(parents=True, exist_ok=True)
    fig.savefig(FIGURES / "gallery_systems.png", dpi=90)
    print(FIGURES / "gallery_systems.png")


if __name__ == "__main__":
    main()
