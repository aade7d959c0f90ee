"""The closing summary of a run on the terminal (rank 0): the status line is the CLI's;
these lines add the final values the scene is about (the panels of histories.png,
plots.py), steps and Newton iterations, the wall time and the files written, one a line."""

from __future__ import annotations

import numpy as np

from .plots import (choose_panels, loaded_point, point_label, relative_power_residual,
                    support_name, support_reaction, unit, unwrapped_angle)

FILES = {
    "scene.toml": "the scene, copied verbatim",
    "timeseries.csv": "the time series, one row per step",
    "timeseries.json": "the same columns as JSON",
    "summary.json": "model and why, status, final values, warnings, versions, files",
    "timings.json": "wall-clock seconds of set-up, integration, output, pictures",
    "histories.png": "the plots of what the scene is about",
    "rod.bp": "ParaView >= 5.13 (ADIOS2VTXReader): the deformed rod and its fields",
    "rod.pvd": "any ParaView (PVD reader): the same steps and fields as rod.bp",
    "rod": "the .vtu files of rod.pvd, one a step",
    "animation.gif": "the moving rod (a GIF: no ffmpeg on the PATH for an MP4)",
    "animation.mp4": "the moving rod (an MP4, H.264, by the system's ffmpeg)",
    "snapshots.png": "selected frames and the colour field along s",
    "spacetime.png": "phi(s, t) and u_d(s, t) as images",
    "checkpoint": "the states for --resume",
    "buckle.json": "dolfin-rod buckle: critical load factors about the end state",
    "buckle.bp": "ParaView (ADIOS2VTXReader): the buckling modes, one step per mode",
    "modes.json": "dolfin-rod modes: natural frequencies about the end state",
    "modes.bp": "ParaView (ADIOS2VTXReader): the vibration modes, one step per mode",
    "buckle.png": "the buckling modes' shapes and their critical load factors",
    "modes.png": "the vibration modes' shapes and their frequencies",
}


def _vector(row: dict, stem: str) -> np.ndarray:
    return np.array([row[f"{stem}_{c}"] for c in "xyz"])


def _text(x) -> str:
    return "[" + ", ".join(f"{v:.4g}" for v in x) + "]" if np.ndim(x) else f"{x:.4g}"


def _rods(row: dict, suffix: str) -> list[tuple[str, str]]:
    """(column prefix, line prefix) of each rod having column <prefix><suffix>: ("", "")
    for a single rod, ("upper.", "upper: ") for the rods of a system."""
    prefixes = [k[:-len(suffix)] for k in row if k.endswith(suffix)]
    return [(p, f"{p[:-1]}: " if p else "") for p in prefixes]


def final_values(rows: list[dict], scene) -> list[str]:
    """One line per panel of histories.png (per rod of a system for the tip and the
    reactions): its quantity at the end of the run."""
    units, last, first = scene["scene"].get("units"), rows[-1], rows[0]
    u = lambda kind: "" if unit(kind, units) == "1" else " " + unit(kind, units)  # noqa: E731
    moved = lambda rod="": _text(_vector(last, f"{rod}tip_position")   # noqa: E731
                                 - _vector(first, f"{rod}tip_position"))
    lines, panels = [], choose_panels(scene, last)
    # a tip whose displacement force_extension's line gives already (an end force's)
    loaded = loaded_point(scene) if "force_extension" in panels else None
    for panel in panels:
        if panel == "tip_deflection":
            lines += [f"{name}tip displacement {moved(rod)}{u('length')}"
                      for rod, name in _rods(last, "tip_position_x")
                      if loaded is None or loaded[2] != f"{rod}tip"]
        elif panel == "tip_rotation" and "tip_quaternion_0" in last:
            q = np.array([[r[f"tip_quaternion_{i}"] for i in range(4)] for r in rows])
            theta, axis = unwrapped_angle(q)
            lines.append(f"tip rotation {theta[-1]:.4g} rad = {theta[-1] / (2 * np.pi):.4g} "
                         f"turns about {_text(axis)}")
        elif panel == "end_torque":
            value = last["end_torsion"] if "end_torsion" in last else \
                _vector(last, "reaction_couple_end")
            lines.append(f"end torque {_text(value)}{u('moment')}")
        elif panel == "force_extension":
            rod, key, point = loaded_point(scene)
            force = rod["loads"][key].vector()(last["time"])
            shift = _vector(last, f"{point}_position") - _vector(first, f"{point}_position")
            lines.append(f"{key.replace('_', ' ')} {_text(force)}{u('force')}, "
                         f"{point_label(rod, key, point)} displacement {_text(shift)}"
                         f"{u('length')}")
        elif panel == "reactions":
            lines += [_reaction(last, scene, rod, name, u)
                      for rod, name in _rods(last, "reaction_force_start_x")]
        elif panel == "twist" and "end_rotation" in last:
            lines.append(f"end rotation phi(1) {last['end_rotation']:.4g}, mean natural twist "
                         f"{last['mean_natural_twist']:.4g}")
        elif panel == "twist" and "writhe" in last:     # a self-contact rod's Tw and Wr
            lines.append(f"twist Tw {last['twist']:.4g}, writhe Wr {last['writhe']:.4g}, "
                         f"Tw + Wr {last['twist'] + last['writhe']:.4g} turns")
        elif panel == "energy":
            lines.append(f"K + Psi {last['free_energy'] + last['kinetic_energy']:.4g}"
                         f"{u('energy')}, dissipated {last['total_dissipation']:.4g}"
                         f"{u('energy')}")
        elif panel == "power_residual" and len(rows) > 2:
            lines.append(power_line(np.nanmax(relative_power_residual(rows)[1:])))
    return lines


# above this relative residual the line says what the balance leaves out
LARGE_POWER_RESIDUAL = 0.05


def power_line(largest: float) -> str:
    """The closing line of the power balance; a large residual is explained, not only
    shown: D is the material's and the loads' dissipation, so what the time integrator
    damps numerically (generalized-alpha with rho_inf < 1; rho_inf = 0 with obstacles)
    and what happens within a step (an impact) stays in the residual."""
    line = f"power balance: largest relative residual after the first step {largest:.2g}"
    if largest > LARGE_POWER_RESIDUAL:
        line += (" (the balance's D leaves out the time integrator's numerical damping and "
                 "events shorter than a step, such as impacts: docs/outputs.md)")
    return line


def _reaction(last: dict, scene, rod: str, name: str, u) -> str:
    """The reaction line of one rod's support at s = 0 (force, and couple if held; a
    clamped ring's weld: its two end nodes' summed)."""
    def reaction(kind: str) -> np.ndarray:
        return np.array([support_reaction(last.__getitem__, scene, rod, kind, c)
                         for c in "xyz"])
    text = f"{name}reaction at {support_name(scene)}: force {_text(reaction('force'))}"
    if f"{rod}reaction_couple_start_x" not in last:
        return text + u("force")
    return f"{text}{u('force')}, couple {_text(reaction('couple'))}{u('moment')}"


def closing_lines(summary: dict, rows: list[dict], scene, wall: float,
                  files: list[str]) -> list[str]:
    """The lines after the status line (rows: the run's time series)."""
    out = [f"  {line}" for line in (final_values(rows, scene) if len(rows) > 1 else [])]
    steps = f"  steps {summary.get('steps')}"
    if "newton_iterations" in summary:
        steps += (f", Newton iterations {summary['newton_iterations']}, rejected steps "
                  f"{summary.get('rejected_steps', 0)}")
    out.append(f"{steps}; wall time {wall:.2f} s")
    out.append("  files:")
    width = max(len(f) for f in files) + 2
    out += [f"    {f:<{width}}{FILES.get(f, '')}" for f in files]
    return out
