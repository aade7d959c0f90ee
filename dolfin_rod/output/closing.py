"""The closing summary of a run on the terminal (rank 0): the status line is the CLI's;
these lines add the final values the scene is about (the panels of histories.png,
plots.py), steps and Newton iterations, the wall time and the files written, one a line."""

from __future__ import annotations

import numpy as np

from .plots import choose_panels, relative_power_residual, unit, unwrapped_angle

FILES = {
    "scene.toml": "the scene, copied verbatim",
    "timeseries.csv": "the time series, one row per step",
    "timeseries.json": "the same columns as JSON",
    "summary.json": "model and why, status, final values, versions, files",
    "timings.json": "wall-clock seconds of set-up, integration, output, pictures",
    "histories.png": "the plots of what the scene is about",
    "rod.bp": "ParaView >= 5.13 (ADIOS2VTXReader): the deformed rod and its fields",
    "rod.pvd": "any ParaView (PVD reader): the same steps and fields as rod.bp",
    "rod": "the .vtu files of rod.pvd, one a step",
    "animation.gif": "the moving rod",
    "snapshots.png": "selected frames and the colour field along s",
    "spacetime.png": "phi(s, t) and u_d(s, t) as images",
    "checkpoint": "the states for --resume",
}


def _vector(row: dict, stem: str) -> np.ndarray:
    return np.array([row[f"{stem}_{c}"] for c in "xyz"])


def _text(x) -> str:
    return "[" + ", ".join(f"{v:.4g}" for v in x) + "]" if np.ndim(x) else f"{x:.4g}"


def final_values(rows: list[dict], scene) -> list[str]:
    """One line per panel of histories.png: its quantity at the end of the run."""
    units, last, first = scene["scene"].get("units"), rows[-1], rows[0]
    u = lambda kind: "" if unit(kind, units) == "1" else " " + unit(kind, units)  # noqa: E731
    moved = lambda: _text(_vector(last, "tip_position")   # noqa: E731
                          - _vector(first, "tip_position"))
    lines = []
    for panel in choose_panels(scene, last):
        if panel == "tip_deflection" and "tip_position_x" in last:
            lines.append(f"tip displacement {moved()}{u('length')}")
        elif panel == "tip_rotation" and "tip_quaternion_0" in last:
            q = np.array([[r[f"tip_quaternion_{i}"] for i in range(4)] for r in rows])
            theta, axis = unwrapped_angle(q)
            lines.append(f"tip rotation {theta[-1]:.4g} rad = {theta[-1] / (2 * np.pi):.4g} "
                         f"turns about {_text(axis)}")
        elif panel == "end_torque":
            value = last["end_torsion"] if "end_torsion" in last else \
                _vector(last, "reaction_couple_right")
            lines.append(f"end torque {_text(value)}{u('moment')}")
        elif panel == "force_extension":
            force = scene["loads"]["end_force"].vector()(last["time"])
            lines.append(f"end force {_text(force)}{u('force')}, tip displacement "
                         f"{moved()}{u('length')}")
        elif panel == "reactions" and "reaction_force_left_x" in last:
            text = f"reaction at s = 0: force {_text(_vector(last, 'reaction_force_left'))}"
            if "reaction_couple_left_x" in last:
                text += (f"{u('force')}, couple "
                         f"{_text(_vector(last, 'reaction_couple_left'))}{u('moment')}")
            lines.append(text if "reaction_couple_left_x" in last else text + u("force"))
        elif panel == "twist":
            lines.append(f"end rotation phi(1) {last['end_rotation']:.4g}, mean natural twist "
                         f"{last['mean_natural_twist']:.4g}")
        elif panel == "energy":
            lines.append(f"K + Psi {last['free_energy'] + last['kinetic_energy']:.4g}"
                         f"{u('energy')}, dissipated {last['total_dissipation']:.4g}"
                         f"{u('energy')}")
        elif panel == "power_residual" and len(rows) > 2:
            lines.append("power balance: largest relative residual after the first step "
                         f"{np.nanmax(relative_power_residual(rows)[1:]):.2g}")
    return lines


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
