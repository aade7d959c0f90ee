"""A run's pictures drawn side by side (issue 30, target 2): the first one in a forked
child process while this process draws the others, so that on two cores the pictures
cost about the largest one instead of their sum (matplotlib is imported and its fonts
loaded once, before the fork).  The run waits for the child: a failure
in it is raised here (RuntimeError naming the picture, its traceback printed by the
child), and Ctrl-C stops both, the half-drawn files removed.  Without os.fork, or for
one picture, they are drawn one after the other here.

A ``Painter`` (issue 30, target 3) is a process forked at a run's start: it imports
matplotlib (0.4 s) while the run imports DOLFINx and integrates, then waits; at the end
the run sends it the pictures (pickled: module functions and their data) and it draws
them as above, side by side.  The run never imports matplotlib then.  Pictures that do
not pickle (a function made in a test) are drawn in the run's process as before."""

from __future__ import annotations

import functools
import os
import pickle
import signal
import sys
import time
import traceback
import warnings
from contextlib import contextmanager
from pathlib import Path
from typing import Callable

Picture = tuple[str, Callable[[], None]]


def draw_pictures(pictures: list[Picture], folder: Path, side_by_side: bool,
                  painter: Painter | None = None) -> tuple[dict[str, float], list[str]]:
    """Draw each (file name, draw) into ``folder``: the seconds each took and the names
    of those not drawn (Ctrl-C).  ``side_by_side``: the first in a child process (only
    where no MPI peer shares the process's memory: one rank).  Ctrl-C here stops this
    process's drawing and waits for the child's picture (a second Ctrl-C ends it).
    ``painter``: a Painter started before, which draws them all if they pickle."""
    if painter is not None and painter.send(pictures, folder):
        return painter.collect([name for name, _ in pictures])
    child = None
    if side_by_side and len(pictures) > 1 and hasattr(os, "fork"):
        _warm_matplotlib()
        child = _Child(*pictures[0], folder)
    own = pictures[1:] if child else pictures
    seconds: dict[str, float] = {}
    for i, (name, draw) in enumerate(own):
        t0 = time.perf_counter()
        try:
            draw()
        except KeyboardInterrupt:
            (folder / name).unlink(missing_ok=True)     # half drawn
            missing = [n for n, _ in own[i:]]
            try:
                return seconds, missing + (_collect(child, seconds) if child else [])
            except RuntimeError:         # its traceback is printed: the run stops anyway
                return seconds, missing + [child.name]
        except BaseException:
            if child:
                child.stop()
            raise
        seconds[name] = time.perf_counter() - t0
    return seconds, _collect(child, seconds) if child else []


@functools.cache
def _warm_matplotlib() -> None:
    """Once per process (a Painter's drawing then does not lay its text out again: 5 ms
    of CPU): import pyplot and lay out one text and one power of ten (mathtext, as a log
    axis' labels: its parser is built at its first use, 0.1-0.2 s) before the fork: the
    child inherits them instead of importing and loading the fonts a second time (0.3-0.5
    s of CPU).  Pillow's image writers (PNG, GIF: loaded at the first save) and its drawing
    modules (the GIF's frames) too: 5-15 ms that each process paid when it drew."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import PIL.Image
    from PIL import ImageDraw, ImageFont  # noqa: F401
    PIL.Image.preinit()
    fig = plt.figure(figsize=(1, 1))
    fig.text(0.5, 0.5, "t [s]")
    fig.text(0.5, 0.2, "$\\mathdefault{10^{-5}}$")
    fig.canvas.draw()
    plt.close(fig)


def _collect(child: _Child, seconds: dict[str, float]) -> list[str]:
    """Wait for the child (Ctrl-C meanwhile ends it): [] with its seconds, or [its
    picture] if it was interrupted; RuntimeError if it failed."""
    try:
        drawn = child.wait()
    except KeyboardInterrupt:
        return child.stop()
    if drawn is None:
        return [child.name]
    seconds[child.name] = drawn
    return []


class _Child:
    """One picture drawn in a forked process; its drawing time comes back by a pipe."""

    def __init__(self, name: str, draw: Callable[[], None], folder: Path):
        self.name, self.path = name, folder / name
        read, write = os.pipe()
        sys.stdout.flush()
        sys.stderr.flush()
        with warnings.catch_warnings():     # "multi-threaded, fork may deadlock": the
            warnings.simplefilter("ignore", DeprecationWarning)   # child takes no lock
            self.pid = os.fork()                                  # of another thread
        if self.pid == 0:
            os.close(read)
            _draw_and_exit(draw, self.path, write)
        os.close(write)
        self.read: int | None = read
        self.text, self.code = b"", None

    def wait(self) -> float | None:
        """The child's drawing seconds; None if it was interrupted; RuntimeError if its
        drawing failed.  Again after a Ctrl-C here: goes on where it stopped."""
        if self.read is not None:
            while chunk := os.read(self.read, 64):
                self.text += chunk
            os.close(self.read)
            self.read = None
        if self.code is None:
            self.code = os.waitstatus_to_exitcode(os.waitpid(self.pid, 0)[1])
        code = self.code
        if code == 0:
            return float(self.text)
        self.path.unlink(missing_ok=True)
        if code in (130, -signal.SIGINT, -signal.SIGTERM):
            return None
        raise RuntimeError(f"drawing {self.name} failed in its process (exit status {code};"
                           " its error is printed above)")

    def stop(self) -> list[str]:
        """End the child (after Ctrl-C here): [its picture] unless it was complete."""
        try:
            os.kill(self.pid, signal.SIGTERM)
        except ProcessLookupError:
            pass
        try:
            return [] if self.wait() is not None else [self.name]
        except RuntimeError:
            return [self.name]


def _draw_and_exit(draw: Callable[[], None], path: Path, pipe: int) -> None:
    """In the child: draw, send the seconds, and leave without the parent's exit handlers
    (MPI, PETSc): 0 drawn, 130 interrupted, 1 failed (traceback on stderr)."""
    status = 1
    try:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        t0 = time.perf_counter()
        draw()
        os.write(pipe, repr(time.perf_counter() - t0).encode())
        status = 0
    except KeyboardInterrupt:
        path.unlink(missing_ok=True)
        status = 130
    except BaseException:
        traceback.print_exc()
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(status)


@contextmanager
def painting(wanted: bool):
    """A Painter while the block runs (None if not ``wanted`` or without os.fork); it is
    ended and waited for at the block's end, whatever happened."""
    painter = Painter() if wanted and hasattr(os, "fork") else None
    try:
        yield painter
    finally:
        if painter is not None:
            painter.close()


class Painter:
    """A process forked before the run's imports that warms matplotlib and then draws
    the run's pictures (``send``, ``collect``), or ends without drawing (``close``, or
    the run's process ending: the end of its pipe).  One rank only (no MPI call in it).
    Ctrl-C during the run does not reach its waiting; while it draws, Ctrl-C (to the
    terminal's process group, or to the run, which passes it on) stops its drawing as
    in draw_pictures."""

    def __init__(self):
        job_read, self._job = os.pipe()
        self._result, result_write = os.pipe()
        sys.stdout.flush()
        sys.stderr.flush()
        with warnings.catch_warnings():       # as _Child: the child takes no lock of
            warnings.simplefilter("ignore", DeprecationWarning)    # another thread
            self.pid = os.fork()
        if self.pid == 0:
            os.close(self._job)
            os.close(self._result)
            _paint_and_exit(job_read, result_write)
        os.close(job_read)
        os.close(result_write)
        self.text, self.code = b"", None

    def send(self, pictures: list[Picture], folder: Path) -> bool:
        """Hand the pictures to the painter; False (the painter ended) if they do not
        pickle."""
        try:
            job = pickle.dumps((pictures, folder))
        except (pickle.PicklingError, AttributeError, TypeError):
            self.close()
            return False
        try:
            _write_all(self._job, job)
        except BrokenPipeError:        # it ended (its error printed): collect says so
            pass
        finally:
            os.close(self._job)
            self._job = None
        return True

    def collect(self, names: list[str]) -> tuple[dict[str, float], list[str]]:
        """Wait for the painter: the seconds of each picture and those not drawn
        (Ctrl-C: all of ``names`` if the painter was interrupted before it answered);
        RuntimeError if it failed.  Ctrl-C here is passed on to it."""
        while self.code is None:
            try:
                while chunk := os.read(self._result, 65536):
                    self.text += chunk
                self.code = os.waitstatus_to_exitcode(os.waitpid(self.pid, 0)[1])
            except KeyboardInterrupt:
                _signal(self.pid, signal.SIGINT)
        os.close(self._result)
        answer = pickle.loads(self.text) if self.text else None
        if self.code == 0 and answer is not None:
            return answer
        if self.code in (130, -signal.SIGINT, -signal.SIGTERM):
            return {}, names
        raise RuntimeError(f"drawing the pictures failed in their process (exit status "
                           f"{self.code}: {answer or 'its error is printed above'})")

    def close(self) -> None:
        """End the painter without pictures (if none were sent) and wait for it."""
        if self._job is not None:
            os.close(self._job)
            self._job = None
        if self.code is None:
            self.code = os.waitstatus_to_exitcode(os.waitpid(self.pid, 0)[1])
            os.close(self._result)


def _write_all(fd: int, data: bytes) -> None:
    """All of ``data`` to the pipe ``fd``; BrokenPipeError if its reader ended.  SIGPIPE
    is ignored first (Python's own setting, which PETSc's signal handler replaces when it
    initialises: a painter killed with the run's other processes then ended the run
    through PETSc's abort, MPI_ABORT, instead of this error)."""
    if hasattr(signal, "SIGPIPE"):
        signal.signal(signal.SIGPIPE, signal.SIG_IGN)
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


def _signal(pid: int, signum: int) -> None:
    try:
        os.kill(pid, signum)
    except ProcessLookupError:
        pass


def _paint_and_exit(job: int, result: int) -> None:
    """In the painter: warm matplotlib, read the job to its end, draw it side by side,
    send the result; exit 0 (also with no job), 130 interrupted, 1 failed (traceback on
    stderr), without the run's exit handlers."""
    status = 1
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)       # the run's Ctrl-C is the run's
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        _warm_matplotlib()
        data = b""
        while chunk := os.read(job, 65536):
            data += chunk
        if data:
            signal.signal(signal.SIGINT, signal.default_int_handler)
            pictures, folder = pickle.loads(data)
            drawn = draw_pictures(pictures, folder, True)
            signal.signal(signal.SIGINT, signal.SIG_IGN)    # drawn: a late Ctrl-C passed
            _write_all(result, pickle.dumps(drawn))         # on by the run changes nothing
        status = 0
    except KeyboardInterrupt:
        status = 130
    except BaseException as err:
        traceback.print_exc()
        _write_all(result, pickle.dumps(f"{type(err).__name__}: {err}"))
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(status)
