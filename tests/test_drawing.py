"""output/drawing.py: a run's pictures drawn side by side (issue 30, target 2).

Each test "picture" writes the id of the process that drew it, so the tests see which
process drew what; a failure or a Ctrl-C in the child must reach the run as it would
have when drawn in the run's own process."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from functools import partial
from pathlib import Path

import pytest

from dolfin_rod.output.drawing import draw_pictures, painting

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "gravity_cantilever.toml"


def writes_pid(path):
    return lambda: path.write_text(str(os.getpid()))


def fails():
    raise ValueError("no such panel")


def interrupted():
    raise KeyboardInterrupt


def drawn_by(path) -> int:
    return int(path.read_text())


def test_first_picture_in_a_child_the_others_here(tmp_path):
    names = ["histories.png", "animation.gif", "snapshots.png"]
    seconds, missing = draw_pictures([(n, writes_pid(tmp_path / n)) for n in names],
                                     tmp_path, side_by_side=True)
    assert missing == [] and sorted(seconds) == sorted(names)
    assert all(s >= 0.0 for s in seconds.values())
    assert drawn_by(tmp_path / names[0]) != os.getpid()
    assert drawn_by(tmp_path / names[1]) == drawn_by(tmp_path / names[2]) == os.getpid()


@pytest.mark.parametrize("pictures", [1, 3])
def test_one_after_the_other_without_side_by_side_or_for_one(tmp_path, pictures):
    names = [f"p{k}.png" for k in range(pictures)]
    side_by_side = pictures == 1      # one picture: drawn here even side by side
    _, missing = draw_pictures([(n, writes_pid(tmp_path / n)) for n in names], tmp_path,
                               side_by_side=side_by_side)
    assert missing == [] and all(drawn_by(tmp_path / n) == os.getpid() for n in names)


def test_a_failure_in_the_child_is_raised_naming_the_picture(tmp_path, capfd):
    with pytest.raises(RuntimeError, match="drawing histories.png failed"):
        draw_pictures([("histories.png", fails), ("a.gif", writes_pid(tmp_path / "a.gif"))],
                      tmp_path, side_by_side=True)
    assert drawn_by(tmp_path / "a.gif") == os.getpid()     # the others were drawn
    assert "no such panel" in capfd.readouterr().err        # the child's traceback


def test_a_failure_here_is_raised_and_the_child_ended(tmp_path):
    with pytest.raises(ValueError, match="no such panel"):
        draw_pictures([("h.png", writes_pid(tmp_path / "h.png")), ("a.gif", fails)],
                      tmp_path, side_by_side=True)


def test_ctrl_c_in_the_child_leaves_its_picture_missing(tmp_path):
    def half_drawn():
        (tmp_path / "h.png").write_text("half")
        raise KeyboardInterrupt

    seconds, missing = draw_pictures(
        [("h.png", half_drawn), ("a.gif", writes_pid(tmp_path / "a.gif"))], tmp_path,
        side_by_side=True)
    assert missing == ["h.png"] and not (tmp_path / "h.png").exists()
    assert list(seconds) == ["a.gif"]


def test_ctrl_c_here_waits_for_the_childs_picture(tmp_path):
    """Ctrl-C stops this process's drawing; the child's picture is completed."""
    seconds, missing = draw_pictures([("h.png", writes_pid(tmp_path / "h.png")),
                                      ("a.gif", interrupted)], tmp_path, side_by_side=True)
    assert missing == ["a.gif"] and list(seconds) == ["h.png"]
    assert drawn_by(tmp_path / "h.png") != os.getpid()


def test_a_second_ctrl_c_ends_the_child(tmp_path):
    """Ctrl-C while waiting for the child's picture ends the child: both are missing,
    and the run does not wait for the child's drawing."""
    import threading
    import time

    def slow():
        time.sleep(30)
        (tmp_path / "h.png").write_text("late")

    def interrupted_and_again():
        threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT)).start()
        raise KeyboardInterrupt

    t0 = time.perf_counter()
    _, missing = draw_pictures([("h.png", slow), ("a.gif", interrupted_and_again)],
                               tmp_path, side_by_side=True)
    assert missing == ["a.gif", "h.png"] and not (tmp_path / "h.png").exists()
    assert time.perf_counter() - t0 < 10       # the child was ended, not waited for


# -- the Painter: a process started before the run's imports draws every picture ----------

def write_pid(path):
    path.write_text(str(os.getpid()))


def painted(pictures, folder):
    """draw_pictures with a Painter started (and ended) around it."""
    with painting(True) as painter:
        return draw_pictures(pictures, folder, side_by_side=True, painter=painter)


def test_a_painter_draws_every_picture_in_other_processes(tmp_path):
    """The pictures (module functions with their data: they pickle) are drawn by the
    painter, side by side: none by this process."""
    names = ["histories.png", "animation.gif", "snapshots.png"]
    seconds, missing = painted([(n, partial(write_pid, tmp_path / n)) for n in names],
                               tmp_path)
    assert missing == [] and sorted(seconds) == sorted(names)
    pids = [drawn_by(tmp_path / n) for n in names]
    assert os.getpid() not in pids
    assert pids[0] != pids[1] == pids[2]        # histories.png in the painter's child


def test_pictures_that_do_not_pickle_are_drawn_here(tmp_path):
    names = ["h.png", "a.gif"]
    _, missing = painted([(n, writes_pid(tmp_path / n)) for n in names], tmp_path)
    assert missing == [] and drawn_by(tmp_path / "a.gif") == os.getpid()


def test_a_failure_in_the_painter_is_raised(tmp_path, capfd):
    with pytest.raises(RuntimeError, match="drawing histories.png failed"):
        painted([("histories.png", fails), ("a.gif", partial(write_pid, tmp_path / "a.gif"))],
                tmp_path)
    assert drawn_by(tmp_path / "a.gif") != os.getpid()
    assert "no such panel" in capfd.readouterr().err


def test_ctrl_c_in_the_painter_leaves_its_pictures_missing(tmp_path):
    seconds, missing = painted([("h.png", partial(write_pid, tmp_path / "h.png")),
                                ("a.gif", interrupted)], tmp_path)
    assert missing == ["a.gif"] and list(seconds) == ["h.png"]


def test_a_painter_given_no_pictures_ends():
    with painting(True) as painter:
        pid = painter.pid
    assert painter.code == 0
    with pytest.raises(ChildProcessError):      # waited for: no zombie left
        os.waitpid(pid, 0)


def test_a_painter_killed_with_the_run_is_a_failed_picture_not_an_abort(tmp_path):
    """A painter killed before the run sends it the pictures (`pkill -f` of the run's
    command line kills both): with PETSc initialised (its signal handler catches
    SIGPIPE and aborts) the send sees a broken pipe and collect reports the painter's
    end, so the run can keep its rows and exit with its own status."""
    script = ("import os, signal, time, functools; from petsc4py import PETSc; "
              "from dolfin_rod.output.drawing import painting\n"
              "with painting(True) as p:\n"
              "    os.kill(p.pid, signal.SIGKILL); time.sleep(0.5)\n"
              "    assert p.send([('a.png', functools.partial(print, 'x'))], None)\n"
              "    try:\n"
              "        p.collect(['a.png'])\n"
              "    except RuntimeError as e:\n"
              "        print('reported:', e)\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          cwd=ROOT, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "reported: drawing the pictures failed in their process (exit status -9" in \
        done.stdout


def test_a_run_does_not_import_matplotlib(tmp_path):
    """`dolfin-rod run` draws its pictures in the painter: matplotlib (0.4 s) is imported
    there, while the run imports DOLFINx; the pictures are complete.  Nor scipy.sparse
    (the stability check's banded Cholesky, 0.13 s of CPU): a dynamic rod that does not
    start in equilibrium checks no stability."""
    script = ("import sys; from dolfin_rod import run; "
              f"r = run({str(SCENE)!r}, out={str(tmp_path / 'run')!r}, quiet=True); "
              "print(r.summary['pictures'], 'matplotlib' in sys.modules, "
              "'scipy.sparse' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         check=True, cwd=ROOT)
    assert out.stdout.split()[-3:] == ["complete", "False", "False"], out.stdout
    assert {"histories.png", "snapshots.png"} <= {p.name for p in (tmp_path / "run").iterdir()}



def test_the_painter_unpickles_a_run_s_pictures_without_the_fe_stack(tmp_path):
    """The pictures a run sends its painter (module functions and LineSamples, pickled)
    load in a process that has imported what the run had when it forked the painter
    (output/writer.py) without importing UFL, DOLFINx, PETSc, Basix or FFCx: such an
    import (UFL: 60-150 ms) would lie on the pictures' path (issue 30, target 2)."""
    import pickle

    import numpy as np

    from dolfin_rod.output import animation
    from dolfin_rod.output.line_fields import LineSample
    s = np.linspace(0.0, 1.0, 3)
    sample = LineSample(s, s[1:] - 0.25, {"centre_line": np.zeros((3, 3))}, {})
    job = pickle.dumps(([("a.gif", partial(animation.rod_animation, [(0.0, sample)],
                                           tmp_path / "a.gif"))], tmp_path))
    painter = ("import pickle, sys; from dolfin_rod.output import writer; "
               "pickle.loads(sys.stdin.buffer.read()); "
               "print(*sorted({m.split('.')[0] for m in sys.modules} & "
               "{'dolfinx', 'petsc4py', 'ufl', 'basix', 'ffcx'}))")
    out = subprocess.run([sys.executable, "-c", painter], input=job, capture_output=True,
                         check=True, cwd=ROOT)
    assert out.stdout.decode().split() == [], out.stdout
