"""Checkpoints of a run: ``<run>/checkpoint/step-N/`` (adios4dolfinx ``state.bp`` and
``meta.json``), written into ``step-N.partial`` and published by one atomic rename, then
the older ones of this run removed: a crash at any moment leaves the last complete
checkpoint, never a state of one step with the metadata of another.  Clean-up deletes
only the checkpoints this run wrote or resumed from, never through a symbolic link (a
``checkpoint/`` that links to a shared folder keeps everything else in it).

meta.json holds the SHA-256 of every file of state.bp and of its own content; resuming
verifies both before opening state.bp (an edited step or time, a truncated or flipped
data file is refused), then that the scene's physics (``Scene.physics``), the model and
the number of degrees of freedom are those of the checkpoint (a fingerprint), before
anything is written.
"""

from __future__ import annotations

import errno
import hashlib
import json
import math
import os
import shutil
import traceback
from pathlib import Path

from ..mpi import agree
from .run_folders import OutputError, on_root
from .vtx import adios2_os_error, quietly


class Checkpoints:
    """The checkpoints of one run in ``folder``: ``sim`` (the integrator) supplies the
    fields and state, ``scene`` the physics the checkpoint must match."""

    def __init__(self, folder: Path, scene, sim, comm):
        self.folder, self.scene, self.sim, self.comm = Path(folder), scene, sim, comm
        self.own: list[Path] = []     # checkpoints of this run: the only ones removed
        self.started_from: dict | None = None   # where the run started (from_run.py)
        self.last_size = 0            # bytes of the last state.bp written (rank 0)

    def _size_estimate(self, named: dict) -> int:
        """Collective: an upper estimate of state.bp's bytes before it is written: 3 x
        the values, dofmaps and mesh in memory + 16 KiB of ADIOS2 metadata (measured on
        a rod of 4, 32, 128 cells: 11.6, 38.8, 132 KB for estimates of 22, 58, 182 KB);
        later checkpoints take the last one's size if larger."""
        from ..fem.compat import geometry_dofmap     # DOLFINx: not at a check's import
        mesh = self.sim.fields[0].function_space.mesh
        local = sum(f.x.array.nbytes + f.function_space.dofmap.list.nbytes
                    for f in named.values()) + mesh.geometry.x.nbytes \
            + geometry_dofmap(mesh).nbytes
        return 3 * self.comm.allreduce(local) + 16384

    def _named_functions(self) -> tuple[dict, dict]:
        """The model's checkpointed functions by name, and the rest of its state."""
        state = self.sim.state()
        functions = state.pop("functions", {})
        named = {f"field_{i}": f for i, f in enumerate(self.sim.fields)} | functions
        return named, state

    def fingerprint(self) -> dict:
        """What a checkpoint must match: the scene's physics, the model, the dofs."""
        named, _ = self._named_functions()
        dofs = {name: global_size(f) for name, f in named.items()}
        data = {"scene": self.scene.physics(), "model": self.sim.name, "dofs": dofs}
        data = json.loads(json.dumps(data))          # tuples -> lists, as read back
        digest = hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()
        return {**data, "sha256": digest}

    def write(self, step: int, t: float, balance: dict) -> None:
        """Collective: the state after ``step`` (and the power ``balance`` state) so that
        ``resume`` continues exactly, written to step-N.partial and made visible by one
        rename (module docstring)."""
        root = self.folder / "checkpoint"
        partial, final = root / f"step-{step:09d}.partial", root / f"step-{step:09d}"

        named, state = self._named_functions()
        size = max(self._size_estimate(named), self.last_size)

        def make_partial():
            root.mkdir(exist_ok=True)
            remove_without_following(partial)     # left by a crash of this run
            check_room(root, size)
            partial.mkdir()
        on_root(self.comm, make_partial, f"cannot write a checkpoint in {root}")
        failure = None
        try:       # a failure on any rank: every rank stops here (mpi.agree)
            real = agree(self.comm, lambda: _write_state(partial / "state.bp", named),
                         (RuntimeError, OSError))
        except (RuntimeError, OSError) as err:
            reason = adios2_os_error(err, partial) if isinstance(err, RuntimeError) else err
            failure = reason.strerror or str(reason)
            quietly(lambda: traceback.clear_frames(err.__traceback__))  # adios4dolfinx's
        if failure is not None:                                         # broken engine
            on_root(self.comm, lambda: remove_without_following(partial),
                    f"cannot remove {partial}")
            raise OutputError(f"cannot write a checkpoint in {root}: {failure}")
        meta = {"step": step, "time": t, "model": self.sim.name, "sim": state, "real": real,
                "balance": balance, "fingerprint": self.fingerprint(),
                "integrator": {"method": self.sim.describe(), "dt": self.scene["time"]["dt"]},
                "from_run": self.started_from, "counters": self._counters()}

        def publish():
            meta["state_sha256"] = file_digests(partial / "state.bp")
            write_checkpoint_meta(partial, {**meta, "sha256": meta_digest(meta)})
            partial.rename(final)
            self.last_size = sum(f.stat().st_size for f in (final / "state.bp").iterdir())
            if not self.scene["outputs"]["keep_checkpoints"]:
                for old in self.own:
                    if old != final:
                        remove_without_following(old)
            self.own = [final]
        self.comm.barrier()                            # every rank's state.bp is written
        on_root(self.comm, publish, f"cannot write a checkpoint in {root}")

    def restore(self, meta: dict) -> dict:
        """Collective: check the model and dofs against ``meta`` (read_checkpoint_meta),
        then restore the model; returns the power-balance state.  Nothing is written."""
        mine = self.fingerprint()
        if meta["fingerprint"]["sha256"] != mine["sha256"]:
            raise OutputError(f"cannot resume from {meta['folder']}: "
                              + fingerprint_difference(meta["fingerprint"], mine))
        named, _ = self._named_functions()
        read_functions(Path(meta["folder"]), meta, named)
        self.sim.restore(meta["sim"])
        stats = getattr(self.sim, "stats", None)
        for name, count in meta.get("counters", {}).items():   # the summary counts the
            setattr(stats, name, count)                        # whole run, not the resume
        self.own = [Path(meta["folder"])]            # replaced by this run's next one
        return meta["balance"]

    def _counters(self) -> dict:
        """The integrator's step counters (StepStats) so far, as numbers."""
        stats = getattr(self.sim, "stats", None)
        return {} if stats is None else {name: int(count) for name, count in
                                         vars(stats).items()}


def global_size(f) -> int:
    """The number of values of the function ``f`` over all ranks (its fingerprint's dofs)."""
    return f.function_space.dofmap.index_map.size_global * f.function_space.dofmap.index_map_bs


def read_functions(folder: Path, meta: dict, named: dict) -> None:
    """Collective: the functions ``named`` (name -> Function) from the checkpoint in
    ``folder`` (its state.bp, written on any number of ranks; those on a real space from
    its meta.json ``meta``)."""
    import adios4dolfinx
    for name, f in named.items():
        if name in meta["real"]:
            f.x.array[:] = meta["real"][name][0]   # one global value (owned + ghost)
        else:
            adios4dolfinx.read_function(folder / "state.bp", f, time=0.0, name=name)
        f.x.scatter_forward()


def file_digests(folder: Path) -> dict[str, str]:
    """SHA-256 of every file under ``folder`` (state.bp), by relative path."""
    digests = {}
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        with path.open("rb") as f:
            digests[str(path.relative_to(folder))] = hashlib.file_digest(f, "sha256") \
                .hexdigest()
    return digests


def meta_digest(meta: dict) -> str:
    """SHA-256 of meta.json's content without its own ``sha256`` entry."""
    data = {k: v for k, v in meta.items() if k != "sha256"}
    return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()


def integrity_problem(folder: Path, meta) -> str | None:
    """Why the checkpoint in ``folder`` (its meta.json content ``meta``) is not the one
    written (an edit, a truncated or flipped file), or None if its checksums match."""
    if not isinstance(meta, dict) or "sha256" not in meta or "state_sha256" not in meta:
        return "its meta.json has no checksums (damaged, or written by an older dolfin-rod)"
    if meta_digest(meta) != meta["sha256"]:
        return "its meta.json does not match the checksum written with it (edited or damaged)"
    try:
        found = file_digests(folder / "state.bp")
    except OSError as err:
        return f"its state.bp cannot be read ({err.strerror or err})"
    expected = meta["state_sha256"]
    changed = sorted(set(found) ^ set(expected)) or [
        name for name in sorted(found) if found[name] != expected[name]]
    if changed:
        return (f"its state.bp ({', '.join(changed[:3])}) does not match the checksums in "
                "meta.json (truncated, edited or damaged)")
    return None


# meta.json's entries and their kinds (a resume reads each): a writer's bug or another
# program could pass the checksum with content no resume can use
META_KINDS = {"step": int, "time": float, "model": str, "sim": dict, "real": dict,
              "balance": dict, "fingerprint": dict}


def content_problem(meta: dict) -> str | None:
    """Why meta.json's content cannot be resumed from (a missing entry, one of the wrong
    kind, a negative step, a time that is not a finite number), or None."""
    for key, kind in META_KINDS.items():
        value = meta.get(key)
        ok = (isinstance(value, (int, float)) and not isinstance(value, bool)
              and math.isfinite(value)) if kind is float else (
            isinstance(value, kind) and not isinstance(value, bool))
        if not ok or (key == "step" and value < 0):
            what = {int: "an integer >= 0", float: "a finite number", str: "a string",
                    dict: "a table"}[kind]
            return f"meta.json: {key} must be {what}, got {value!r}"
    return None


def remove_without_following(path: Path) -> None:
    """Delete a checkpoint folder; a symbolic link is unlinked, never followed."""
    if path.is_symlink():
        path.unlink()
    elif path.is_dir():
        shutil.rmtree(path)


def check_room(folder: Path, size: int) -> None:
    """OSError (ENOSPC, or EFBIG for the process's file-size limit, RLIMIT_FSIZE) if
    ``size`` bytes cannot be written to one new file in ``folder``: ADIOS2 meets a full
    disk inside collective calls, where a rank that fails leaves the others waiting
    (issue 28 item 18), so a checkpoint that cannot fit is refused before it starts."""
    import resource
    stat = os.statvfs(folder)
    free = stat.f_bavail * stat.f_frsize
    if size > free:
        raise OSError(errno.ENOSPC, f"{os.strerror(errno.ENOSPC)} (a checkpoint needs about "
                                    f"{size} bytes, {free} are free)")
    limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    if limit != resource.RLIM_INFINITY and size > limit:
        raise OSError(errno.EFBIG, f"{os.strerror(errno.EFBIG)} (a checkpoint needs about "
                                   f"{size} bytes in one file; this process may write "
                                   f"{limit}: ulimit -f)")


def _write_state(path: Path, named: dict) -> dict[str, list[float]]:
    """Collective: the functions of ``named`` into state.bp (adios4dolfinx); those on a
    real space (which adios4dolfinx cannot read back in parallel) returned as lists."""
    import adios4dolfinx
    real: dict[str, list[float]] = {}
    for name, f in named.items():
        if _is_real(f):
            f.x.scatter_forward()
            real[name] = f.x.array.tolist()
        else:
            adios4dolfinx.write_function_on_input_mesh(path, f, time=0.0, name=name)
    return real


def write_checkpoint_meta(folder: Path, meta: dict) -> None:
    """Rank 0: meta.json of a checkpoint (its own function so that tests can make a
    crash happen between state.bp and meta.json)."""
    (folder / "meta.json").write_text(json.dumps(meta))


def read_checkpoint_meta(run: Path, comm, scene) -> dict:
    """Collective: the newest complete checkpoint of ``run`` (``meta["folder"]``),
    refused with OutputError unless it was written by a scene with the same physics
    (Scene.physics) and ends before time.t_end.  Reads only."""
    def newest():
        root = run / "checkpoint"
        done = sorted(p for p in root.glob("step-*") if p.suffix != ".partial"
                      and (p / "meta.json").is_file()) if root.is_dir() else []
        if not done:
            raise OutputError(f"--resume: no complete checkpoint in {root} (the scene "
                              "needs outputs.checkpoint_every > 0)")
        try:
            meta = json.loads((done[-1] / "meta.json").read_bytes())
        except ValueError as err:           # not UTF-8, not JSON
            raise OutputError(f"cannot resume from {done[-1]}: its meta.json is not JSON "
                              f"({err}); nothing was changed") from None
        problem = integrity_problem(done[-1], meta) or content_problem(meta)
        if problem:
            raise OutputError(f"cannot resume from {done[-1]}: {problem}; nothing was "
                              "changed")
        return {**meta, "folder": str(done[-1])}
    meta = on_root(comm, newest, f"--resume: cannot read the checkpoint of {run}")
    theirs = meta.get("fingerprint", {}).get("scene")
    mine = json.loads(json.dumps(scene.physics()))
    if theirs != mine:
        raise OutputError(f"cannot resume from {meta['folder']}: "
                          + fingerprint_difference({"scene": theirs}, {"scene": mine}))
    if meta["time"] >= scene["time"]["t_end"]:
        raise OutputError(f"cannot resume from {meta['folder']}: it is at t = "
                          f"{meta['time']:g}, not before time.t_end = "
                          f"{scene['time']['t_end']:g}")
    return meta


def differences(theirs, mine, path: str = "") -> list[tuple[str, object, object]]:
    """(dotted path, their value, mine) wherever two JSON-like tables differ, "model" and
    "scene" first (the likely cause before the dofs), then by name."""
    if not (isinstance(theirs, dict) and isinstance(mine, dict)):
        return [] if theirs == mine else [(path, theirs, mine)]
    first = ("model", "scene")
    return [d for k in sorted(set(theirs) | set(mine), key=lambda k: (k not in first, k))
            for d in differences(theirs.get(k), mine.get(k), f"{path}.{k}" if path else k)]


def fingerprint_difference(theirs: dict, mine: dict) -> str:
    """The first entries where a checkpoint's fingerprint and this run's differ."""
    diffs = [f"{path}: {a!r} in the checkpoint, {b!r} now"
             for path, a, b in differences(theirs, mine)]
    shown = "; ".join(d.removeprefix("scene.") for d in diffs[:4])
    return (f"it was written by a different run ({shown or 'unreadable fingerprint'}"
            f"{'; ...' if len(diffs) > 4 else ''}); nothing was changed")


def _is_real(f) -> bool:
    """A scifem real space (one global unknown, e.g. the uniform natural twist)."""
    V = f.function_space
    return (V.dofmap.index_map.size_global * V.dofmap.index_map_bs == 1
            and V.mesh.topology.index_map(V.mesh.topology.dim).size_global > 1)
