"""A line for the user when kernels compile for long (the first run of a kind of model on
a cold FFCx cache is otherwise silent for up to a minute).

    with compile_notice.listening(sys.stdout):  # run.py, rank 0, not --quiet
        ... build and run the model ...         # form_cache.compile_forms -> watching()

A compile that lasts longer than ``after`` seconds (SLOW_COMPILE: a warm cache answers in
well under that) writes "compiling kernels (first run only, about N s)" to the stream,
once per listening; N is the seconds the last cold compile on this machine took in total
(kept in ``seconds.json`` beside the form cache), "up to a minute" before any was
measured.  The line comes from a small child process (``sleep; printf``) started with
the compile and stopped when it ends first: the compile holds Python's interpreter lock
for seconds at a time, so a thread of this process could not speak in time.  Nothing is
said without a stream (the library, tests, --quiet).
"""

from __future__ import annotations

import json
import os
import subprocess
import time
from contextlib import contextmanager
from pathlib import Path

SLOW_COMPILE = 2.0      # s
_STATE: dict = {"stream": None, "after": SLOW_COMPILE, "told": False, "seconds": 0.0}


def _record(folder: Path) -> Path:
    return folder / "seconds.json"


def estimate(folder: Path) -> str:
    """'about N s' from the last cold compile measured here, else 'up to a minute'."""
    try:
        seconds = float(json.loads(_record(folder).read_text())["cold_compile_seconds"])
        return f"about {max(1, round(seconds))} s"
    except (OSError, ValueError, KeyError, TypeError):
        return "up to a minute"


@contextmanager
def listening(stream, after: float = SLOW_COMPILE):
    """Within the block, a compile longer than ``after`` s writes its line to ``stream``
    (a file with a descriptor; None or a stream without one, as pytest's capture or a
    notebook's output, nothing) once."""
    _STATE.update(stream=_with_descriptor(stream), after=after, told=False, seconds=0.0)
    try:
        yield
    finally:
        _STATE.update(stream=None, after=SLOW_COMPILE)


def _with_descriptor(stream):
    """``stream`` if a child process can write to it (it has a file descriptor), else
    None."""
    try:
        stream.fileno()
    except (AttributeError, OSError, ValueError):   # io.UnsupportedOperation is both
        return None
    return stream


def _speaker(stream, after: float, text: str):
    """A child process that writes ``text`` to ``stream`` after ``after`` seconds."""
    stream.flush()
    return subprocess.Popen(["sh", "-c", 'sleep "$0" && printf "%s\\n" "$1"', f"{after:g}",
                             text], stdin=subprocess.DEVNULL, stdout=stream,
                            stderr=subprocess.DEVNULL)


@contextmanager
def watching(folder: Path):
    """Around one compile: its line if it outlasts ``after`` (see module); the seconds
    of slow compiles are added up and recorded in ``folder`` for the next estimate."""
    child = None
    if _STATE["stream"] is not None and not _STATE["told"]:
        child = _speaker(_STATE["stream"], _STATE["after"],
                         f"compiling kernels (first run only, {estimate(folder)})")
    start = time.perf_counter()
    try:
        yield
    finally:
        if child is not None:
            if child.poll() is None:
                child.kill()
            _STATE["told"] = child.wait() == 0
        elapsed = time.perf_counter() - start
        if elapsed > SLOW_COMPILE:
            _STATE["seconds"] += elapsed
            _save(folder, _STATE["seconds"])


def _save(folder: Path, seconds: float) -> None:
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tmp = _record(folder).with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(json.dumps({"cold_compile_seconds": seconds}))
        tmp.replace(_record(folder))
    except OSError:
        pass        # a read-only cache: no estimate kept
