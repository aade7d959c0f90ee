"""The modes of an analysis of a run's end state (``dolfin-rod buckle``, ``modes``):
``<kind>.json`` (the table: one row per mode), ``<kind>.bp`` (ParaView, the
ADIOS2VTXReader: one step per mode, "time" = the mode's number, the centre line
displaced by the mode scaled to a largest displacement of 0.1 L (a system: L its longest
rod), with the point data ``mode_displacement`` and ``mode_rotation`` of the mode scaled
to 1), ``<kind>.png``
(output/mode_picture.py: the same displaced centre lines, one panel per mode) and the
table as text.  The mode shapes are gathered on rank 0 in the order of s (line_fields.py);
rank 0 writes.
"""

from __future__ import annotations

import json
from pathlib import Path

from .line_fields import LineSampler
from .mode_picture import draw_modes
from .run_folders import on_root
from .vtx import LineVTX

__all__ = ["write_modes", "table"]

AMPLITUDE = 0.1        # the drawn mode's largest displacement, in rod lengths


def write_modes(folder: Path, model, kind: str, rows: list[dict], shapes: list[dict],
                comm) -> list[str]:
    """``<kind>.json`` and ``<kind>.bp`` in ``folder`` (see the module); the file names."""
    import dolfinx.fem as fem
    space = model.f["displacement"].function_space    # P1 vectors: the rotation alike
    fields = {name: fem.Function(space) for name in ("mode_displacement", "mode_rotation")}
    observables = {"centre_line": model.observables()["centre_line"], **fields}
    sampler = LineSampler(model.mesh, observables, tuple(observables))
    samples = []
    for shape in shapes:
        fields["mode_displacement"].x.array[:] = shape["displacement"]
        fields["mode_rotation"].x.array[:] = shape["rotation"]
        samples.append(sampler.sample())
    names = [f"{kind}.json", f"{kind}.bp", f"{kind}.png"]

    def write() -> None:
        (folder / names[0]).write_text(json.dumps({"kind": kind, "modes": rows}, indent=1))
        vtx = LineVTX(folder / names[1])
        displaced = []
        for k, sample in enumerate(samples, start=1):
            displaced.append(sample.point["centre_line"] + AMPLITUDE * model.length *
                             sample.point["mode_displacement"])
            vtx.write(float(k), displaced[-1], {n: sample.point[n] for n in fields}, {},
                      sample.segments())
        vtx.close()
        if samples:
            draw_modes(folder / names[2], samples[0].point["centre_line"], displaced,
                       [_title(row) for row in rows], HEADINGS[kind], samples[0].segments())
    on_root(comm, write, f"cannot write the {kind} modes in {folder}")
    return names


HEADINGS = {"buckle": "buckling modes (largest displacement 0.1 L)",
            "modes": "vibration modes (largest displacement 0.1 L)"}


def _title(row: dict) -> str:
    """A mode's panel title: its number and load factor or frequency."""
    if "load_factor" in row:
        return f"mode {row['mode']}: load factor {row['load_factor']:.6g}"
    growth = f", grows {row['growth_rate']:.3g}" if row.get("growth_rate") else ""
    return f"mode {row['mode']}: omega {row['omega']:.6g} (f {row['frequency']:.6g}{growth})"


def table(rows: list[dict]) -> str:
    """The rows as a text table (the keys of the first row as its columns)."""
    if not rows:
        return "(no modes)"
    keys = list(rows[0])
    cells = [[f"{r[k]:.6g}" if isinstance(r[k], float) else str(r[k]) for k in keys]
             for r in rows]
    widths = [max(len(k), *(len(c[i]) for c in cells)) for i, k in enumerate(keys)]
    line = lambda items: "  ".join(s.rjust(w) for s, w in zip(items, widths))  # noqa: E731
    return "\n".join([line(keys)] + [line(c) for c in cells])

