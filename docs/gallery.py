"""The pictures of docs/gallery.md: runs the bundled scenes of issue 25 (sliding turning
clamp, on a vertical and on an inclined rail, compliant support, rotational damping) and
plots each against its closed form.

    ./rodenv python3 docs/gallery.py        # ~1 min; writes docs/figures/gallery_*.png
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from dolfin_rod import load_scene, run_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / "docs" / "figures"
QUIET = {"outputs.animation": False, "outputs.plots": False, "outputs.fields": False,
         "outputs.progress": False}


def series(name: str) -> dict:
    folder = ROOT / "results" / "gallery" / name
    run_scene(load_scene(ROOT / "scenes" / f"{name}.toml", QUIET), folder, quiet=True,
              overwrite=True)
    rows = np.genfromtxt(folder / "timeseries.csv", delimiter=",", names=True, deletechars="")
    return {k: rows[k] for k in rows.dtype.names}


def hanging_twist(ax) -> None:
    s = series("hanging_twist")
    scene = load_scene(ROOT / "scenes" / "hanging_twist.toml")
    derived = scene["material"]["derived"]
    weight = 0.5 + derived["density"] * 9.81 * 1.0
    ax.plot(s["time"], s["reaction_force_end_z"], label="top clamp: vertical force (N)")
    ax.axhline(weight, color="k", ls=":", label="W + rho A g L")
    twist = 6.0 * np.clip(s["time"] / 2.0, 0, 1) ** 2 * (3 - 2 * np.clip(s["time"] / 2.0, 0, 1))
    ax.plot(s["time"], -100 * s["reaction_couple_end_z"], label="top clamp: torque x 100 (N m)")
    ax.plot(s["time"], 100 * derived["A"][2] * twist, "k--", lw=0.8,
            label="GJ phi(t)/L x 100")
    ax.set(xlabel="t (s)", title="hanging weight on a sliding, turning clamp")
    ax.legend(fontsize=7)


def inclined_clamp(ax) -> None:
    s = series("inclined_clamp")
    t = np.linspace(0, 1, 50)
    weight = 0.5 * t                                     # the ramped weight W(t)
    top, carriage = (np.sqrt(sum(s[f"rod.reaction_force_{end}_{c}"] ** 2 for c in "xyz"))
                     for end in ("end", "start"))
    ax.plot(s["time"], top, "o", label="top clamp: |force| (N)")
    ax.plot(t, weight / np.sqrt(3), "k--", lw=0.8, label="W/sqrt 3: the weight along the rail")
    ax.plot(s["time"], carriage, "s", label="carriage: |force| (N)")
    ax.plot(t, weight * np.sqrt(2 / 3), "k:", label="W sqrt(2/3): the weight across it")
    ax.set(xlabel="t (s)", title="weight on a clamp sliding along a rail (1,1,1)/sqrt 3")
    ax.legend(fontsize=7)


def sprung_cantilever(ax) -> None:
    s = series("sprung_cantilever")
    load = 5.0 * s["time"]
    EI = 2.1e11 * 0.04 * 0.005**3 / 12
    ax.plot(load, 100 * s["tip_position_x"], "o-", label="tip deflection (cm)")
    ax.plot(load, 100 * (load / (3 * EI) + load / 200.0), "k--",
            label="P L^3/(3EI) + P L^2/k_r (linear)")
    ax.plot(load, 100 * load / 200.0, "k:", label="support's part P L^2/k_r")
    ax.set(xlabel="tip force P (N)", title="cantilever on a rotational spring")
    ax.legend(fontsize=7)


def spin_up(ax) -> None:
    s = series("spin_up")
    tau = 1000.0 * math.pi * 0.01**4 / 2 / 1e-4
    t = np.linspace(0, 1, 200)
    ax.plot(s["time"], s["tip_rotation_angle"], "o", ms=3, label="tip rotation angle (rad)")
    ax.plot(t, t - tau * (1 - np.exp(-t / tau)), "k--",
            label="(m/c)(t - tau (1 - exp(-t/tau)))")
    ax.set(xlabel="t (s)", title="spin-up against rotational damping")
    ax.legend(fontsize=7)


def main() -> None:
    fig, axes = plt.subplots(1, 4, figsize=(20, 4.2))
    for draw, ax in zip((hanging_twist, inclined_clamp, sprung_cantilever, spin_up), axes):
        draw(ax)
    fig.tight_layout()
    FIGURES.mkdir(parents=True, exist_ok=True)
    fig.savefig(FIGURES / "gallery_supports.png", dpi=110)
    print(FIGURES / "gallery_supports.png")


if __name__ == "__main__":
    main()
