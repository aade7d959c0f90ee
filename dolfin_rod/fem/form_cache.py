"""Compiled forms shared by every model of the same structure (issue 12: set-up time).

Building a rod's step forms costs seconds of UFL processing (derivative expansion,
replacement, signatures) even with a warm FFCx cache, while the kernels depend only on
the model's structure, not on its mesh size or data.  A cache entry is keyed by a
structure key (the UFL signatures of the model's residual plus what the integrator
bakes in); it keeps the compiled kernels and, for each of their coefficients and
constants, its position in an ordered list of the objects of the instance (the
"registry": the model's Functions and Constants in creation order, then the
integrator's and the assembler's own).  A new instance with the same key binds the
compiled kernels to its own objects, mesh and spaces without building any UFL.

The step kernels (residual and Jacobian, ``compile_forms``) are compiled with -O1 and,
on x86-64, the host's instruction set (``KERNEL_FLAGS``): the rod's Jacobian kernel, 16k
flops of straight-line code per cell, 4.20 (DOLFINx's -O2) -> 3.27 us per cell, as fast
as -O3 -march=native, and compiled in 6 s instead of 7 s (-O2) or 25 s (-O3
-march=native, longer than the 10 s another process waits for it; docs/performance.md).  A macro naming the host
CPU (model and instruction-set flags) is part of the flags, so FFCx's cache key differs
between CPUs: a cache shared by several machines (a home folder on NFS) never hands one
a kernel built for another.  ``DOLFIN_ROD_KERNEL_FLAGS`` (space-separated compiler
flags) replaces the default, e.g. "-O2" for portable kernels.

Entries are also kept on disk (a small JSON file per key naming the FFCx module and
its form, beside FFCx's own cache), so that the first model of a structure in a new
process skips the UFL processing too (1.7 s -> ~0.1 s at 32 cells, warm FFCx cache).
The disk key adds the DOLFINx/FFCx versions and a hash of this package's source: any
change of the code that builds forms invalidates it.  Serial runs only: under MPI the
ranks could disagree on a hit (another process writing or clearing the folder between
their reads) and then deadlock in the collective JIT of the ones that missed.
"""

from __future__ import annotations

import hashlib
import importlib.machinery
import importlib.util
import json
import os
import platform
import re
import signal
import threading
import time
import warnings
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import dolfinx
import dolfinx.fem as fem
import ffcx
import numpy as np
import ufl
from dolfinx.fem import IntegralType
from dolfinx.fem.forms import form_cpp_class
from mpi4py import MPI

from . import compat, compile_notice
from .gathered_form import LazyForms

_ENTRIES: dict[str, list] = {}
_MODULES: dict[str, object] = {}
_KEYS_OF_STRUCTURES: dict[str, str] = {}     # structure as data -> signature key
_FOLDER = (Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache"))
           / "dolfin_rod" / "form_cache")


def _host_cpu() -> str:
    """A short fingerprint of this machine's CPU: model name and instruction-set flags."""
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
        text = " ".join(next((ln for ln in lines if ln.startswith(k)), "")
                        for k in ("model name", "flags"))
    except OSError:
        text = ""
    text = text or f"{platform.machine()} {platform.processor()}"
    return hashlib.sha1(text.encode()).hexdigest()[:12]


def kernel_flags() -> list[str]:
    """DOLFIN_ROD_KERNEL_FLAGS if set, else -O1 and, on x86-64, -march=native."""
    given = os.environ.get("DOLFIN_ROD_KERNEL_FLAGS")
    if given is not None:
        return given.split()
    native = ["-march=native"] if platform.machine() in ("x86_64", "AMD64") else []
    return ["-O1", *native, "-g0"]


KERNEL_FLAGS = [*kernel_flags(), f"-DDOLFIN_ROD_HOST_CPU={_host_cpu()}"]


# Another process compiling the same kernel is waited for this long (FFCx: 10 s): a
# cold compile of the rod's kernels takes 6 s on an idle core and several times that
# on a loaded machine, where runs started together (a sweep) timed out at 10 s.
JIT_WAIT = 300     # s


@contextmanager
def interrupts_held():
    """SIGINT and SIGTERM are held while FFCx compiles and delivered after: FFCx keeps
    the half-made module of a KeyboardInterrupt (it cleans up after an Exception only),
    and every later run on this machine would wait for it and fail (TimeoutError)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    held = (signal.SIGINT, signal.SIGTERM)
    previous = {sig: signal.signal(sig, lambda signum, _: caught.append(signum))
                for sig in held}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if caught:
            signal.raise_signal(caught[0])     # to the handler the caller had


def compile_forms(forms):
    """fem.form of a form or (nested) list of forms, with the step kernels' flags; flags a
    user gave (DOLFIN_ROD_KERNEL_FLAGS) that do not compile are named in the error.  A
    long compile (a cold FFCx cache) is announced (compile_notice.py); Ctrl-C waits for
    its end (interrupts_held)."""
    try:
        with compile_notice.watching(_FOLDER), interrupts_held():
            return jit_form(forms, KERNEL_FLAGS)
    except Exception as err:
        if "DOLFIN_ROD_KERNEL_FLAGS" not in os.environ:
            raise
        raise RuntimeError(f"DOLFIN_ROD_KERNEL_FLAGS={os.environ['DOLFIN_ROD_KERNEL_FLAGS']!r}:"
                           f" the step kernels did not compile with these flags ({err})") from err


def jit_form(forms, flags: list[str] | None = None):
    """fem.form of a form or (nested) list of forms (with compiler ``flags`` if given),
    waiting up to JIT_WAIT for another process compiling the same kernel.  A compile
    killed before its end (SIGKILL, out of memory) leaves FFCx's lock, the module's .c
    file without its .c.cached, and every later run waited for it and failed: a lock
    that was older than JIT_WAIT when this wait began (so no compile finished in twice
    that time) is removed once, with a warning naming it, and the compile redone."""
    options = {"timeout": JIT_WAIT} | ({"cffi_extra_compile_args": flags} if flags else {})
    began = time.time()
    with modules_found_by_path():
        try:
            return fem.form(forms, jit_options=options)
        except Exception as err:
            if not _removed_stale_lock(err, forms, began - JIT_WAIT):
                raise
            return fem.form(forms, jit_options=options)


@contextmanager
def modules_found_by_path():
    """FFCx's cache look-up (``get_cached_module``) with the compiled module found by its
    path.  FFCx 0.9 to 0.11 find it with an importlib FileFinder whose cache they first
    invalidate, so every hit lists FFCx's whole cache directory: four files per kernel
    ever compiled (17,500 on the project's machine: 60 ms a hit at load 12, 38 % of
    tests/test_rod.py's time).  FFCx issue 886, fixed upstream by PR 887 ("locate cached
    modules by path"), which this follows while the package's forms are compiled."""
    from ffcx.codegeneration import jit
    own = jit.get_cached_module
    jit.get_cached_module = cached_module
    try:
        yield
    finally:
        jit.get_cached_module = own


def cached_module(module_name: str, object_names: list[str], cache_dir, timeout: int):
    """As FFCx's get_cached_module: None, None after creating ``module_name``.c (this
    process compiles it); else, once its ``.c.cached`` marks it compiled (waiting up to
    ``timeout`` s), the module's objects and the module, loaded from the file
    ``module_name`` + an extension suffix (the names FileFinder tries, in its order)."""
    cache_dir = Path(cache_dir)
    c_file = cache_dir.joinpath(module_name).with_suffix(".c")
    ready = c_file.with_suffix(".c.cached")
    cache_dir.mkdir(exist_ok=True, parents=True)
    try:
        with open(c_file, "x"):
            return None, None
    except FileExistsError:
        pass
    for _ in range(timeout):
        if ready.exists():
            path = next((p for p in (cache_dir / (module_name + suffix) for suffix
                                     in importlib.machinery.EXTENSION_SUFFIXES)
                         if p.is_file()), None)
            if path is None:
                raise ModuleNotFoundError("Unable to find JIT module.")
            spec = importlib.util.spec_from_file_location(module_name, path)
            module = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(module)
            return [getattr(module.lib, name) for name in object_names], module
        time.sleep(1)
    raise TimeoutError("JIT compilation timed out, probably due to a failed previous "
                       f"compile. Try cleaning cache (e.g. remove {c_file}) or increase "
                       "timeout option.")


_LOCK_IN_MESSAGE = re.compile(r"remove (.+\.c)\)")


def _removed_stale_lock(err: Exception, forms, stale_before: float) -> bool:
    """Whether the JIT failure ``err`` was a wait for a lock last written before the
    time ``stale_before``, now removed.  Under MPI, DOLFINx's JIT fails on every rank at
    once, with the message naming the lock on rank 0 only: rank 0 decides, tells the
    others."""
    text = str(err)
    if not isinstance(err, TimeoutError) and "JIT" not in text and "just-in-time" not in text:
        return False
    comm = _comm(forms)
    removed = None
    found = _LOCK_IN_MESSAGE.search(text)
    if comm.rank == 0 and found:
        lock = Path(found.group(1))
        if lock.name.startswith("libffcx_") and lock.is_file() \
                and not lock.with_suffix(".c.cached").exists() \
                and lock.stat().st_mtime < stale_before:     # FFCx's module, nothing else
            lock.unlink(missing_ok=True)
            removed = str(lock)
    removed = comm.bcast(removed, root=0) if comm.size > 1 else removed
    if removed:
        warnings.warn(f"removed {removed}: the lock of a kernel compile that was killed "
                      "before its end; compiling that kernel again", RuntimeWarning)
    return removed is not None


def _comm(forms):
    """The communicator of the forms' mesh (DOLFINx's JIT is collective on it)."""
    stack = [forms]
    while stack:
        item = stack.pop()
        if isinstance(item, ufl.Form):
            return item.ufl_domains()[0].ufl_cargo().comm
        if isinstance(item, (list, tuple)):
            stack.extend(item)
    return MPI.COMM_WORLD


@dataclass(frozen=True)
class Kernel:
    """One compiled form and the registry positions of its coefficients, constants."""

    ufcx: object
    module: object
    rank: int
    dtype: str
    integral_types: tuple
    roles: tuple
    const_roles: tuple


def registry(forms) -> list:
    """The Functions and Constants of ``forms`` in creation order (UFL count); of
    gathered_form.LazyForms without making them."""
    if isinstance(forms, LazyForms):
        objs = set(forms.data)
    else:
        objs = set()
        for form in forms:
            objs.update(form.coefficients())
            objs.update(form.constants())
    return sorted(objs, key=lambda c: (isinstance(c, ufl.Constant), c.count()))


def structure_key(forms, *extra, structure: str | None = None) -> str:
    """A key for the kernels of ``forms`` (their UFL signatures) and ``extra`` items.
    ``structure``: the forms' structure as data (SemiDiscreteProblem.structure, e.g.
    rod/structure.py): the key computed for it before in this process is reused, without
    the signatures (most of a second stepper's set-up)."""
    if structure is not None:
        data = hashlib.sha1("|".join([structure, *map(repr, extra)]).encode()).hexdigest()
        if data not in _KEYS_OF_STRUCTURES:
            _KEYS_OF_STRUCTURES[data] = structure_key(forms, *extra)
        return _KEYS_OF_STRUCTURES[data]
    text = "|".join([*(form.signature() for form in forms), *map(repr, extra)])
    return hashlib.sha1(text.encode()).hexdigest()


def text_key(structure: str, *extra) -> str:
    """A key from a model's structure as data and ``extra`` items alone, without UFL
    signatures (which cost the first model in a new process more than a compile): for
    forms that the text determines, such as a rod's diagnostics and reactions (equal
    texts, equal forms up to the values of their data: rod/structure.py).  On disk the
    key adds the hash of this package's source, so no changed code finds an old kernel."""
    return hashlib.sha1("|".join(["text", structure, *map(repr, extra)]).encode()).hexdigest()


def clear(disk: bool = True) -> None:
    """Forget every compiled form in this process and, if ``disk``, on disk (the next
    model of each structure compiles again; without ``disk``: loads it from disk)."""
    _ENTRIES.clear()
    _KEYS_OF_STRUCTURES.clear()
    for path in _FOLDER.glob("*.json") if disk else ():
        path.unlink(missing_ok=True)


def lookup(key: str | None, comm: MPI.Comm, usable: bool = True):
    """The entry of ``key`` (None: none, without communication), or None if any rank of
    ``comm`` (the model's communicator; collective for a key) has none or cannot use it
    (not ``usable``: the caller keeps more than the kernels, such as a blocked system's
    layout of blocks, and has not that): the ranks that missed compile, and DOLFINx's
    JIT is collective on ``comm``.  An entry can be on some ranks only: one stored by a
    model on a communicator of its own (a rank's serial model in an MPI job)."""
    if not key:
        return None
    entry = _entry(key) if usable else None
    if comm.size > 1 and not comm.allreduce(entry is not None, op=MPI.LAND):
        return None
    return entry


def _entry(key: str):
    """This process's entry of ``key``, loaded from disk in serial runs."""
    if key not in _ENTRIES and MPI.COMM_WORLD.size == 1:
        entry = _load(key)
        if entry is not None:
            _ENTRIES[key] = entry
    return _ENTRIES.get(key)


def store(key: str, compiled: list[fem.Form], ufl_forms: list[ufl.Form], objects,
          tagged: bool = False, disk: bool = True) -> None:
    """Remember compiled forms with the registry positions of their data (skipped when a
    form integrates over tagged subdomains, whose tags are not in the registry, unless
    ``tagged``: the caller gives their integration entities to ``bind``); on disk too
    (serial runs) unless not ``disk`` (an entry whose caller keeps more than the kernels,
    such as a blocked system's layout of blocks, in this process only)."""
    if not tagged and any(itg.subdomain_data() is not None for form in ufl_forms
                          for itg in form.integrals()):
        return
    index = {id(obj): i for i, obj in enumerate(objects)}
    entry = []
    for form, uform in zip(compiled, ufl_forms):
        ufcx = form.ufcx_form
        coefficients = uform.coefficients()
        roles = [index[id(coefficients[ufcx.original_coefficient_positions[i]])]
                 for i in range(ufcx.num_coefficients)]
        entry.append(Kernel(ufcx, form.module, form.rank, str(form.dtype),
                            tuple(t.name for t in form.integral_types), tuple(roles),
                            tuple(index[id(c)] for c in uform.constants())))
    _ENTRIES[key] = entry
    if disk and MPI.COMM_WORLD.size == 1:
        _save(key, entry)


def bind(entry, objects, space, mesh, subdomains=None) -> list[fem.Form]:
    """The cached kernels with the data of ``objects``, arguments in ``space`` (or, a
    list, per kernel the list of its arguments' spaces: a blocked system's);
    ``subdomains``: {IntegralType: [(id, integration entities)]} of tagged integrals."""
    spaces = space if isinstance(space, list) else [[space] * k.rank for k in entry]
    return [_bound_form(k, [objects[i] for i in k.roles], [objects[i] for i in k.const_roles],
                        arguments, mesh, subdomains) for k, arguments in zip(entry, spaces)]


def _bound_form(k: Kernel, coefficients, constants, spaces, mesh, subdomains) -> fem.Form:
    """A DOLFINx form from a compiled kernel with other data (the C++ constructor differs
    between DOLFINx 0.9 and 0.11: compat.cpp_form)."""
    pointer = k.module.ffi.cast("uintptr_t", k.module.ffi.addressof(k.ufcx))
    types = [getattr(IntegralType, name) for name in k.integral_types]
    f = compat.cpp_form(form_cpp_class(np.dtype(k.dtype)), pointer, spaces,
                        coefficients, constants, types, mesh, subdomains)
    return fem.Form(f, k.ufcx, None, k.module)


# -- on disk ------------------------------------------------------------------------------


def _disk_key(key: str) -> str:
    if "source" not in _MODULES:
        digest = hashlib.sha1(f"{dolfinx.__version__} {ffcx.__version__}".encode())
        for path in sorted(Path(__file__).resolve().parents[1].rglob("*.py")):
            digest.update(path.read_bytes())
        _MODULES["source"] = digest.hexdigest()
    return hashlib.sha1(f"{key}{_MODULES['source']}{KERNEL_FLAGS}".encode()).hexdigest()


def _form_name(k: Kernel) -> str:
    ffi, lib = k.module.ffi, k.module.lib
    address = int(ffi.cast("uintptr_t", ffi.addressof(k.ufcx)))
    return next(n for n in dir(lib) if n.startswith("form_")
                and int(ffi.cast("uintptr_t", ffi.addressof(lib, n))) == address)


def _save(key: str, entry: list[Kernel]) -> None:
    """Write the entry's JSON record (atomically: other processes may read it)."""
    try:
        record = [{"module": k.module.__name__, "path": k.module.__file__,
                   "form": _form_name(k), "rank": k.rank, "dtype": k.dtype,
                   "integral_types": k.integral_types, "roles": k.roles,
                   "const_roles": k.const_roles} for k in entry]
        _FOLDER.mkdir(parents=True, exist_ok=True)
        path = _FOLDER / f"{_disk_key(key)}.json"
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(json.dumps(record))
        os.replace(tmp, path)
    except (OSError, AttributeError, StopIteration):
        pass  # a read-only cache or a module without a file: memory only


def _load(key: str) -> list[Kernel] | None:
    """The entry recorded on disk, its FFCx modules loaded; None if any part is gone."""
    try:
        record = json.loads((_FOLDER / f"{_disk_key(key)}.json").read_text())
        entry = []
        for r in record:
            if r["path"] not in _MODULES:
                spec = importlib.util.spec_from_file_location(r["module"], r["path"])
                module = importlib.util.module_from_spec(spec)
                spec.loader.exec_module(module)
                _MODULES[r["path"]] = module
            module = _MODULES[r["path"]]
            entry.append(Kernel(getattr(module.lib, r["form"]), module, r["rank"], r["dtype"],
                                tuple(r["integral_types"]), tuple(r["roles"]),
                                tuple(r["const_roles"])))
        return entry
    except (OSError, ValueError, KeyError, ImportError, AttributeError):
        return None
