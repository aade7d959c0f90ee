"""``rod.pvd`` + ``rod/step-NNNNN.vtu``: the fields along the rod as VTK XML files, which
every ParaView (also Debian 12's 5.11) and VisIt open with their built-in readers (File >
Open ``rod.pvd``: the "PVD Reader"); no adios2 needed.  The same steps, points and fields
as ``rod.bp`` (vtx.py): the deformed centre line r(s, t) as the points, point data (s,
d1, d2, d3, ...) and cell data (u, v, u_d, v_d, n, m, xi, ...).

Each step is an UnstructuredGrid of line cells, its arrays Float64 (Int64 for the cells)
written inline as base64 "binary" with a UInt64 byte count before the data (VTK's
layout of uncompressed inline data: header and data encoded as one base64 stream);
``rod.pvd`` is the collection of the steps with their times, rewritten (a new file, then
a rename: it always lists complete files) after a step at most every ``PVD_EVERY``
seconds, and at ``flush`` (a checkpoint: a resume keeps the steps it lists) and
``close``: a rename over a file makes ext4 write the new one out first (1-20 ms a step
waiting for the disk: 0.9-1.4 s of the gravity cantilever's 51 frames at load 13, issue
30).  A run killed (SIGKILL) lists the steps of its last half second in rod.bp but not
in rod.pvd.  Rank 0 writes (the samples are gathered there, line_fields.py).  ``keep_until`` (resume): the steps up to that time are kept, the later
ones removed.

    w = LineVTU(folder / "rod.pvd"); w.write(t, points, {"s": ...}, {"u": ...}); w.close()
    steps = read_pvd(folder / "rod.pvd")    # as vtx.read_vtx: time, points, cells, data
"""

from __future__ import annotations

import base64
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

__all__ = ["LineVTU", "read_pvd", "read_vtu"]

VTK_LINE = 3
PVD_EVERY = 0.5         # s: rod.pvd rewritten after a step at most this often (and flush)


def _encoded(array: np.ndarray) -> str:
    """base64 of a UInt64 byte count followed by the little-endian data."""
    raw = np.ascontiguousarray(array).tobytes()
    return base64.b64encode(np.uint64(len(raw)).astype("<u8").tobytes() + raw).decode()


def _data_array(name: str, values, dtype: str = "<f8") -> str:
    """One inline DataArray: a value per point or cell, flattened components."""
    a = np.asarray(values, dtype=dtype)
    a = a.reshape(len(a), -1) if a.ndim > 1 else a
    components = a.shape[1] if a.ndim > 1 else 1
    kind = "Float64" if dtype == "<f8" else "Int64"
    return (f'<DataArray type="{kind}" Name="{name}" NumberOfComponents="{components}" '
            f'format="binary">{_encoded(a)}</DataArray>')


def vtu_text(points: np.ndarray, cells: np.ndarray, point_data: dict,
             cell_data: dict) -> str:
    """The .vtu of a polyline: ``points`` (n x 3), ``cells`` (m x 2 point indices)."""
    cells = np.asarray(cells, dtype=np.int64)
    arrays = lambda data: "".join(_data_array(k, v) for k, v in data.items())  # noqa: E731
    return ('<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" '
            'byte_order="LittleEndian" header_type="UInt64">\n<UnstructuredGrid>\n'
            f'<Piece NumberOfPoints="{len(points)}" NumberOfCells="{len(cells)}">\n'
            f'<Points>{_data_array("Points", points)}</Points>\n'
            f'<Cells>{_data_array("connectivity", cells.ravel(), "<i8")}'
            f'{_data_array("offsets", 2 * np.arange(1, len(cells) + 1), "<i8")}'
            f'{_data_array("types", np.full(len(cells), VTK_LINE), "<i8")}</Cells>\n'
            f'<PointData>{arrays(point_data)}</PointData>\n'
            f'<CellData>{arrays(cell_data)}</CellData>\n'
            '</Piece>\n</UnstructuredGrid>\n</VTKFile>\n')


def _pvd_text(entries: list[tuple[float, str]]) -> str:
    rows = "".join(f'<DataSet timestep="{t!r}" part="0" file="{f}"/>\n' for t, f in entries)
    return ('<?xml version="1.0"?>\n<VTKFile type="Collection" version="1.0" '
            f'byte_order="LittleEndian">\n<Collection>\n{rows}</Collection>\n</VTKFile>\n')


class LineVTU:
    """Writes steps of a polyline as .vtu files listed in a .pvd (rank 0 only)."""

    def __init__(self, path: Path, keep_until: float | None = None):
        self.path = Path(path)
        self.steps = self.path.with_suffix("")          # rod.pvd -> rod/
        self.entries: list[tuple[float, str]] = []
        if keep_until is not None and self.path.exists():
            self.entries = [(t, f) for t, f in _collection(self.path)
                            if t <= keep_until * (1 + 1e-12)]
        kept = {self.path.parent / f for _, f in self.entries}
        if self.steps.is_dir():
            for old in self.steps.glob("*.vtu"):
                if old not in kept:
                    old.unlink()
        self.steps.mkdir(parents=True, exist_ok=True)
        self._listed: int | None = None       # steps rod.pvd on disk lists (None: unknown)
        self._listed_at = -float("inf")       # time.monotonic() of its last rewrite

    def write(self, t: float, points: np.ndarray, point_data: dict, cell_data: dict,
              cells: np.ndarray | None = None) -> None:
        """One step (``cells`` None: the points in order, one line through all)."""
        n = len(points)
        if cells is None:
            cells = np.column_stack([np.arange(n - 1), np.arange(1, n)])
        name = f"{self.steps.name}/step-{len(self.entries):05d}.vtu"
        (self.path.parent / name).write_text(vtu_text(points, cells, point_data, cell_data))
        self.entries.append((float(t), name))
        if time.monotonic() - self._listed_at >= PVD_EVERY:
            self.flush()

    def flush(self) -> None:
        """rod.pvd listing every step written (if it does not yet)."""
        if self._listed == len(self.entries):
            return
        new = self.path.with_suffix(".pvd-new")
        new.write_text(_pvd_text(self.entries))
        new.replace(self.path)
        self._listed, self._listed_at = len(self.entries), time.monotonic()

    def close(self) -> None:
        """rod.pvd listing every step (nothing else is open between steps)."""
        self.flush()


def _collection(path: Path) -> list[tuple[float, str]]:
    root = ET.parse(path).getroot()
    return [(float(d.get("timestep")), d.get("file")) for d in root.iter("DataSet")]


def _decoded(element) -> np.ndarray:
    raw = base64.b64decode(element.text)
    size = int(np.frombuffer(raw[:8], dtype="<u8")[0])
    dtype = "<f8" if element.get("type") == "Float64" else "<i8"
    a = np.frombuffer(raw[8:8 + size], dtype=dtype)
    k = int(element.get("NumberOfComponents", "1"))
    return a.reshape(-1, k) if k > 1 else a


def read_vtu(path: Path) -> dict:
    """A .vtu of this module: points, cells (m x 2), point and cell data."""
    piece = ET.parse(path).getroot().find("UnstructuredGrid/Piece")
    data = lambda tag: {a.get("Name"): _decoded(a) for a in piece.find(tag)}  # noqa: E731
    cells = data("Cells")
    return {"points": _decoded(piece.find("Points/DataArray")),
            "cells": cells["connectivity"].reshape(-1, 2),
            "point": data("PointData"), "cell": data("CellData")}


def read_pvd(path: Path) -> list[dict]:
    """Every step of a rod.pvd, in the form of vtx.read_vtx: time, points, cells, data."""
    path = Path(path)
    return [{"time": t, **read_vtu(path.parent / f)} for t, f in _collection(path)]
