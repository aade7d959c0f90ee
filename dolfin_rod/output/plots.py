"""histories.png: the time series a scene is about (rank 0, from the rows of the run).

Panels (``outputs.plots``: a list of these names; default chosen by ``choose_panels``
from the scene's supports and loads):

    tip_deflection   tip displacement r(L, t) - r(L, 0), components x, y, z (an end
                     that can move)
    tip_rotation     rotation of the tip about its main axis, unwrapped (cumulative):
                     a 2.5-turn twist reads 5 pi, not 5 pi mod 2 pi (held end
                     rotations; rods turned by an end or distributed couple)
    end_torque       the couple the support at s = L exerts (reaction_couple_end_*);
                     torsion models: the end torsion m(1, t)
    force_extension  the applied end force along its direction against the tip
                     displacement along it (a hysteresis loop when the rod is viscous;
                     a force that varies: ramp, smooth step, table); without an end
                     force, a point force against its point's displacement; a system
                     (by default under arc length only): its first rod with such a
                     force; arc length: the limit point marked
    reactions        force and couple of the support at s = 0 (reaction_*_start_*)
    stability        the count of negative eigenvalues of the stiffness (the column
                     negative_eigenvalues of runs that check stability): 0 is stable
    contact          the total contact force (obstacles: |sum of the force|; segment
                     pairs: the sum of the pair forces' magnitudes) and the smallest gap
                     (scenes with obstacles or contact between segments)
    twist            torsion models: end rotation phi(1, t) and mean natural twist; a
                     clamped rod in self-contact: Lk (end turns) = Tw + Wr
    energy           K + Psi and the dissipated energy int D dt
    power_residual   |d/dt(K + Psi + E_c) + D - P| / power scale (relative_power_residual)

Units: ``scene.units`` ("SI", "pN-nm-s", "pN-nm-ns", "mm-N-s", "mm-N-ms",
"dimensionless": schema.UNITS) names the unit of every axis; a scene without it gets
"scene units".
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..scenes.schema import PANELS, UNITS


def unit(kind: str, units: str | None) -> str:
    """The unit of a quantity kind in the scene's unit system ('scene units' without)."""
    if kind == "angle":
        return "rad"
    return UNITS[units][kind] if units in UNITS else "scene units"


def axis_label(name: str, kind: str, units: str | None) -> str:
    """'name [unit]' in the scene's unit system; 'name [scene units]' without one."""
    return f"{name} [{unit(kind, units)}]"


def time_label(scene, units: str | None) -> str:
    """The time axis' label: the load factor under arc-length continuation (the loads
    linear in it; it turns back at limit points), else 't [time unit]'."""
    if scene["continuation"]["method"] == "arc_length":
        return "load factor t [1] (arc-length continuation)"
    return axis_label("t", "time", units)


def choose_panels(scene, columns) -> list[str]:
    """The panels for the scene: its ``outputs.plots`` if given, else from its supports
    and loads (see module docstring); always ending with energy and power residual."""
    chosen = scene["outputs"]["plots"]
    if isinstance(chosen, tuple):
        return list(chosen)
    cols = set(columns)
    if "end_torsion" in cols:
        return ["end_torque", "twist", "energy", "power_residual"]
    boundary, loads = scene["boundary"], scene["loads"]
    panels = []
    # a system: its tips' panel unless its path is a continuation's (the load path)
    force = loaded_point(scene) if not scene.rods or \
        scene["continuation"]["method"] == "arc_length" else None
    if force is not None and force[0]["loads"][force[1]].type not in ("constant", "step") \
            and (force[1] == "point_force" or force[0]["boundary"]["end"] == "free") \
            and f"{force[2]}_position_x" in cols:
        panels.append("force_extension")
    if boundary.get("end_rotation") is not None and "reaction_couple_end_z" in cols:
        panels += ["end_torque", "twist" if "writhe" in cols else "tip_rotation"]
    if not panels and "tip_quaternion_0" in cols and (
            loads.get("end_couple") is not None or loads.get("distributed_couple") is not None):
        panels.append("tip_rotation")       # a rod turned by couples (spin_up)
    if not panels and scene["geometry"]["closed"] and "writhe" in cols:
        panels.append("twist")      # a ring: Tw, Wr and its link (rod/ring.py)
    tip_moves = (boundary["end"] == "free" or boundary.get("end_displacement") is not None
                 or boundary.get("end_slide") is not None) and not clamped_ring(scene)
    if not panels and tip_moves and any(c.endswith("tip_position_x") for c in cols):
        panels.append("tip_deflection")
    if any(c.endswith(("contact_force_x", "pair_contact_force")) for c in cols):
        panels.append("contact")
    if any(c.endswith("reaction_force_start_x") for c in cols) and len(panels) < 2:
        panels.append("reactions")
    return panels + ["energy", "power_residual"]


def clamped_ring(scene) -> bool:
    """A closed rod clamped at its weld (rod/ring.py): its end nodes, s = 0 and s = L,
    are the one weld point, both held; the weld's reaction is theirs summed (each alone
    is the internal force and couple of the ring there, +-n, +-m, plus its share)."""
    return bool(scene["geometry"]["closed"]) and scene["boundary"]["start"] == "clamped"


def support_reaction(row, scene, rod: str, name: str, c: str):
    """The reaction ``name`` (force, couple) component ``c`` of a rod's support at s = 0
    from a row of the time series (a row or a column getter): a clamped ring's weld
    sums its two end nodes'."""
    value = row(f"{rod}reaction_{name}_start_{c}")
    return value + row(f"{rod}reaction_{name}_end_{c}") if clamped_ring(scene) else value


def support_name(scene) -> str:
    return "the weld (s = 0 and L)" if clamped_ring(scene) else "s = 0"


def unwrapped_angle(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cumulative rotation angle about a fixed axis from unit quaternions q (n x 4,
    scalar first), and that axis: the axis of the largest rotation, signed so that its
    largest component is positive.  theta = 2 atan2(q_v . a, q_0) is unwrapped in steps
    of 2 pi, which also absorbs the sign ambiguity q ~ -q (a jump of 2 pi in theta)."""
    v = q[:, 1:]
    k = int(np.argmax(np.linalg.norm(v, axis=1)))
    norm = np.linalg.norm(v[k])
    if norm == 0.0:
        return np.zeros(len(q)), np.array([0.0, 0.0, 1.0])
    a = v[k] / norm
    a = a * np.sign(a[np.argmax(np.abs(a))]) + 0.0     # (+ 0.0: no "-0" printed)
    return np.unwrap(2.0 * np.arctan2(v @ a, q[:, 0])), a


# below this fraction of the energy per run time the balance's terms are round-off
POWER_FLOOR = 1e-9


def relative_power_residual(rows: list[dict]) -> np.ndarray:
    """|r_k| / S for k >= 1, r_k the power_residual column and S the power scale: the
    largest over the run of |d/dt(K + Psi + E_c)|, D and |P| (the terms of the balance;
    the difference quotient of each interval for the first), at least POWER_FLOOR
    max |K + Psi + E_c| / (t_end - t_0): a rod at rest (every term round-off, ~1e-16 of
    its energy a step) has no residual to speak of, not one of order 1."""
    e = np.array([r["free_energy"] + r["kinetic_energy"] + r.get("contact_energy", 0.0)
                  for r in rows])
    t = np.array([r["time"] for r in rows])
    rates = np.abs(np.diff(e) / np.diff(t))
    floor = POWER_FLOOR * np.max(np.abs(e)) / (t[-1] - t[0]) if t[-1] > t[0] else 0.0
    scale = max(np.max(rates, initial=0.0), floor,
                max(abs(r["dissipation_rate"]) for r in rows),
                max(abs(r["load_power"]) for r in rows))
    residual = np.abs(np.array([r["power_residual"] for r in rows[1:]], dtype=float))
    return residual / scale if scale > 0 else residual


class _Series:
    def __init__(self, rows):
        self.rows = rows
        self.t = np.array([r["time"] for r in rows])

    def __call__(self, key):
        return np.array([self.rows[i][key] for i in range(len(self.rows))], dtype=float)

    def prefixes(self, suffix):
        """'' for a rod, '<name>.' for each rod of a system having column <..>suffix."""
        return [k[:-len(suffix)] for k in self.rows[0] if k.endswith(suffix)]


def _shown(series: dict) -> dict:
    """The series above round-off: max |x| > 1e-9 of the largest of them (all if none)."""
    top = max(np.max(np.abs(x)) for x in series.values())
    kept = {k: x for k, x in series.items() if np.max(np.abs(x)) > 1e-9 * top}
    return kept or series


def _largest(series: dict, n: int) -> dict:
    """Of many reactions (a tripod's 18 were unreadable) the n forces and the n couples
    of the largest max |x|."""
    def top(kind):
        of_kind = [kx for kx in series.items() if kx[0].split(".")[-1][0] == kind]
        return sorted(of_kind, key=lambda kx: -np.max(np.abs(kx[1])))[:n]
    return dict(top("F") + top("M"))


def _tip_deflection(ax, col, units, scene):
    for rod in col.prefixes("tip_position_x"):
        moved = {c: col(f"{rod}tip_position_{c}") for c in "xyz"}
        for c, x in _shown({c: x - x[0] for c, x in moved.items()}).items():
            ax.plot(col.t, x, label=f"{rod}tip {c}")
    ax.legend(fontsize="small")
    return "tip deflection r(L, t) - r(L, 0)", axis_label("displacement", "length", units)


def _tip_rotation(ax, col, units, scene):
    for rod in col.prefixes("tip_quaternion_0"):
        q = np.stack([col(f"{rod}tip_quaternion_{i}") for i in range(4)], axis=1)
        theta, a = unwrapped_angle(q)
        ax.plot(col.t, theta, label=f"{rod}about [{a[0]:.2g}, {a[1]:.2g}, {a[2]:.2g}]")
        ax.text(0.02, 0.9, f"end: {theta[-1] / (2 * np.pi):.3g} turns",
                transform=ax.transAxes, fontsize="small")
    ax.legend(fontsize="small", loc="lower right")
    return "tip rotation (unwrapped, cumulative)", axis_label("angle", "angle", units)


def _end_torque(ax, col, units, scene):
    if "end_torsion" in col.rows[0]:
        ax.plot(col.t, col("end_torsion"))
        return "end torsion m(1, t)", axis_label("m(1, t)", "moment", units)
    for c, m in _shown({c: col(f"reaction_couple_end_{c}") for c in "xyz"}).items():
        ax.plot(col.t, m, label=f"M_{c}")
    ax.legend(fontsize="small")
    return "end torque: couple of the support at s = L", axis_label("couple", "moment", units)


def loaded_point(scene) -> tuple[object, str, str] | None:
    """The force of force_extension: (the scene whose loads hold it, its key, the
    columns' stem of its point): (scene, "end_force", "tip") for an end force, else
    (scene, "point_force", "point0") for a point force (point0 is the first point of the
    point loads: the force's where no couple is elsewhere); a system ([[rods]]): of its
    first rod with such a force, that rod's scene and the stem "<rod>.tip" or
    "<rod>.point0"."""
    own = [(rod.scene, f"{rod.name}.") for rod in scene.rods] or [(scene, "")]
    for rod, prefix in own:
        loads = rod["loads"]
        if loads.get("end_force") is not None:
            return rod, "end_force", prefix + "tip"
        force, couple = loads.get("point_force"), loads.get("point_couple")
        if force is not None and (couple is None or couple.s == force.s):
            return rod, "point_force", prefix + "point0"
    return None


def force_and_displacement(col, scene) -> tuple[np.ndarray, np.ndarray, str, str]:
    """force_extension's curve: the force along its direction e (that of its largest
    value) and its point's displacement along e, the force's key and where its point is
    ("tip", "point s = ..." with the rod's name in a system)."""
    rod, key, point = loaded_point(scene)
    force = rod["loads"][key].vector()
    f = np.array([force(t) for t in col.t])
    k = int(np.argmax(np.linalg.norm(f, axis=1)))
    e = f[k] / max(np.linalg.norm(f[k]), 1e-300)
    x = np.stack([col(f"{point}_position_{c}") for c in "xyz"], axis=1)
    return f @ e, (x - x[0]) @ e, key, point_label(rod, key, point)


def point_label(rod, key: str, point: str) -> str:
    """Where force_extension's point is: "tip" or "point s = ..." (of the rod's
    arc length), "<rod>'s ..." in a system."""
    where = "tip" if point.endswith("tip") else f"point s = {rod['loads'][key].s:g}"
    return f"{point.split('.')[0]}'s {where}" if "." in point else where


def limit_point(force: np.ndarray) -> int | None:
    """The step of the first maximum of the force along a path that turns back (a
    continuation through a limit point), None if it only rises."""
    falls = np.flatnonzero(np.diff(force) < 0)
    return int(falls[0]) if falls.size and falls[0] > 0 else None


def _force_extension(ax, col, units, scene):
    f, d, key, where = force_and_displacement(col, scene)
    ax.plot(d, f)
    top = limit_point(f) if scene["continuation"]["method"] == "arc_length" else None
    if top is not None:
        ax.plot(d[top], f[top], "o", color="C3",
                label=f"limit point: {f[top]:.4g} at {d[top]:.4g}")
        ax.legend(fontsize="small")
    ax.set_xlabel(axis_label(f"displacement of the {where} along the force", "length", units))
    return f"force-displacement ({key.replace('_', ' ')} against its point's motion)", \
        axis_label(key.replace("_", " "), "force", units)


def unloaded(reactions: dict, energy: float, length: float) -> bool:
    """Every reaction (label '[rod.]F_c' or '[rod.]M_c' -> series) below 1e-9 of the
    run's scale: energy / length for the forces, energy for the couples, energy the
    largest of K + Psi and int D dt over the run."""
    scale = {"F": energy / length, "M": energy}
    return all(np.max(np.abs(x)) <= 1e-9 * scale[label.split(".")[-1][0]]
               for label, x in reactions.items())


def _reactions(ax, col, units, scene):
    raw = {f"{rod}{kind}_{c}": support_reaction(col, scene, rod, name, c)
           for rod in col.prefixes("reaction_force_start_x")
           for kind, name in (("F", "force"), ("M", "couple")) for c in "xyz"
           if f"{rod}reaction_{name}_start_{c}" in col.rows[0]}
    energy = max(np.max(np.abs(col("free_energy") + col("kinetic_energy"))),
                 np.max(np.abs(col("total_dissipation"))))
    if unloaded(raw, energy, scene["geometry"]["length"]):
        ax.text(0.5, 0.5, "the support carries no load:\nevery reaction is round-off\n"
                "(below 1e-9 of the run's energy / L)", ha="center", va="center",
                transform=ax.transAxes)
        ax.set_xticks([])
        ax.set_yticks([])
        return f"reactions of the support at {support_name(scene)}", ""
    series = _largest(_shown(raw), 3)
    is_force = {label: label.split(".")[-1][0] == "F" for label in series}
    if not any(is_force.values()):      # forces all round-off: the couples on the axis
        for label, x in series.items():
            ax.plot(col.t, x, "--", label=label)
        ax.legend(fontsize="small")
        return (f"reactions of the support at {support_name(scene)}",
                axis_label("couple (dashed)", "moment", units))
    twin = ax.twinx() if not all(is_force.values()) else None
    for label, x in series.items():
        (ax if is_force[label] else twin).plot(col.t, x, "-" if is_force[label] else "--",
                                               label=label)
    ax.legend(fontsize="small", loc="upper left")
    if twin is not None:
        twin.set_ylabel(axis_label("couple (dashed)", "moment", units))
        twin.legend(fontsize="small", loc="upper right")
    more = f" (the largest {len(series)} of {len(raw)})" if len(series) < len(_shown(raw)) else ""
    return (f"reactions of the support at {support_name(scene)}" + more,
            axis_label("force (solid)", "force", units))


def _contact(ax, col, units, scene):
    forces = {f"{rod}obstacles": np.linalg.norm(
        np.stack([col(f"{rod}contact_force_{c}") for c in "xyz"], axis=1), axis=1)
        for rod in col.prefixes("contact_force_x")}
    forces.update({f"{rod}segment pairs": col(f"{rod}pair_contact_force")
                   for rod in col.prefixes("pair_contact_force")})
    lines = [ax.plot(col.t, f, label=f"{label}: force")[0] for label, f in forces.items()]
    gaps = {f"{rod}obstacles": col(f"{rod}min_gap") for rod in col.prefixes("min_gap")}
    gaps.update({f"{rod}segment pairs": col(f"{rod}min_pair_gap")
                 for rod in col.prefixes("min_pair_gap")})
    if gaps:
        twin = ax.twinx()
        lines += [twin.plot(col.t, g, "--", label=f"{label}: smallest gap")[0]
                  for label, g in gaps.items()]
        twin.set_ylabel(axis_label("smallest gap (dashed)", "length", units))
    ax.legend(handles=lines, fontsize="small", loc="best")   # one legend: no overlap
    return "contact: total force and smallest gap", axis_label("force (solid)", "force", units)


def _stability(ax, col, units, scene):
    from matplotlib.ticker import MaxNLocator
    ax.plot(col.t, col("negative_eigenvalues"), drawstyle="steps-post")
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    return "stability: negative eigenvalues of the stiffness (0: stable)", "count"


def _link(ax, col, units, scene):
    """Self-contact runs of a clamped rod or a ring: twist Tw, writhe Wr, their sum and
    the link Lk = the end's turns, a ring's its own (Calugareanu-White: Lk = Tw + Wr)."""
    tw, wr = col("twist"), col("writhe")
    geo = scene["geometry"]
    if geo["closed"]:       # a ring: its link, kept by the weld (rod/ring.py)
        turns = geo["excess_link"] + geo["reference_curvature"][2] * geo["length"] / (2 * np.pi)
        ax.plot(col.t, np.full(len(col.t), turns), "k", lw=3, alpha=0.3,
                label="Lk: the ring's turns")
    else:
        q = np.stack([col(f"tip_quaternion_{i}") for i in range(4)], axis=1)
        ax.plot(col.t, unwrapped_angle(q)[0] / (2 * np.pi), "k", lw=3, alpha=0.3,
                label="Lk: end turns")
    ax.plot(col.t, tw + wr, "k--", label="Tw + Wr")
    ax.plot(col.t, tw, label="twist Tw")
    ax.plot(col.t, wr, label="writhe Wr")
    ax.legend(fontsize="small")
    return "link = twist + writhe (Calugareanu-White)", "turns [1]"


def _twist(ax, col, units, scene):
    if "writhe" in col.rows[0] and "tip_quaternion_0" in col.rows[0]:
        return _link(ax, col, units, scene)
    if "end_rotation" not in col.rows[0]:   # a rod's "twist" column
        return _column("twist")(ax, col, units, scene)
    ax.plot(col.t, col("end_rotation"), label="end rotation phi(1)")
    ax.plot(col.t, col("mean_natural_twist"), label="mean natural twist")
    ax.legend(fontsize="small")
    return "twist", axis_label("angle / twist", "angle", units)


def _energy(ax, col, units, scene):
    ax.plot(col.t, col("free_energy") + col("kinetic_energy"), label="K + Psi")
    ax.plot(col.t, col("total_dissipation"), label="int D dt")
    ax.legend(fontsize="small")
    return "energy stored and dissipated", axis_label("energy", "energy", units)


def _power_residual(ax, col, units, scene):
    residual = relative_power_residual(col.rows)
    if residual.size and np.max(residual) <= 1e-14:     # (a log axis of zeros: 1e-300)
        ax.text(0.5, 0.5, "balanced to round-off:\nevery relative residual <= 1e-14",
                ha="center", va="center", transform=ax.transAxes)
        ax.set_xticks([])
        ax.set_yticks([])
    else:
        ax.semilogy(col.t[1:], residual + 1e-300)
    return ("power balance: |d/dt(K+Psi) + D - P| / max(|dE/dt|, D, |P|)",
            "relative residual [1]")


def column_kind(name: str) -> str | None:
    """The quantity kind of a time-series column by its name (None: no unit known);
    the dissipation rates and powers are powers, total_dissipation an energy."""
    for stem, kind in (("angular_momentum", "angular_momentum"), ("momentum", "momentum"),
                       ("reaction_force", "force"), ("reaction_couple", "moment"),
                       ("tip_position", "length"), ("energy", "energy"),
                       ("total_dissipation", "energy"), ("dissipation", "power"),
                       ("power", "power"), ("contact_force", "force"),
                       ("friction_force", "force"), ("gap", "length"), ("time", "time")):
        if stem in name:
            return kind
    return None


def _column(name: str):
    """A panel of one CSV column against time (``dolfin-rod plot RUN column``)."""
    def draw(ax, col, units, scene):
        kind = column_kind(name)
        ax.plot(col.t, col(name))
        return name, axis_label(name, kind, units) if kind else name
    return draw


DRAW = {"tip_deflection": _tip_deflection, "tip_rotation": _tip_rotation,
        "end_torque": _end_torque, "force_extension": _force_extension,
        "reactions": _reactions, "contact": _contact, "stability": _stability,
        "twist": _twist, "energy": _energy,
        "power_residual": _power_residual}


def plot_histories(rows: list[dict], path: Path, scene, title: str = "",
                   panels: list[str] | None = None) -> list[str]:
    """histories.png of ``panels`` (names of DRAW or CSV columns; default the scene's,
    choose_panels); returns their names."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    panels = panels or choose_panels(scene, rows[0])
    units = scene["scene"].get("units")
    col = _Series(rows)
    ncols = 2
    nrows = (len(panels) + 1) // 2
    fig, axes = plt.subplots(nrows, ncols, figsize=(11, 3.4 * nrows), squeeze=False)
    for ax, name in zip(axes.flat, panels):
        heading, ylabel = DRAW.get(name, _column(name))(ax, col, units, scene)
        ax.set_title(heading, fontsize=10)
        ax.set_ylabel(ylabel)
        if not ax.get_xlabel():
            ax.set_xlabel(time_label(scene, units))
    for ax in list(axes.flat)[len(panels):]:
        ax.set_visible(False)
    fig.suptitle(title)
    save_laid_out(fig, path, 100)
    plt.close(fig)
    return panels


def save_laid_out(fig, path: Path, dpi: int) -> None:
    """The figure laid out (tight_layout) and saved: matplotlib's tight_layout leaves a
    placeholder layout engine on the figure, for which savefig lays the figure out again
    (a draw without pixels: a quarter of histories.png's time) before drawing it; without
    an engine it draws once, the same pixels.  A PNG is compressed at zlib's level 1, not
    Pillow's 6: the same pixels, files 5-10 % larger, 6 % off histories.png's time."""
    fig.tight_layout()
    fig.set_layout_engine(None)
    png = {"pil_kwargs": {"compress_level": 1}} if Path(path).suffix == ".png" else {}
    fig.savefig(path, dpi=dpi, **png)
