"""The ways into the environment share one install script and one package list per
Debian release; the README's test command (CI) covers every release."""

import os
import re
import sys
import threading
import tomllib
from pathlib import Path

import pytest

import serial_reference
from conftest import Cores, starts_mpi

ROOT = Path(__file__).resolve().parents[1]


def releases() -> dict[str, str]:
    """DOLFINx release -> Debian release, as env/rootfs.sh maps $DOLFINX."""
    rootfs = (ROOT / "env/rootfs.sh").read_text()
    table = dict(re.findall(r"^\s*(\d+\.\d+)\) release=(\w+) ;;", rootfs, re.M))
    assert table, "no DOLFINX -> Debian release table in env/rootfs.sh"
    return table


def test_rootfs_maps_each_dolfinx_release_to_a_debian_release():
    assert releases() == {"0.9": "trixie", "0.11": "sid"}
    rootfs = (ROOT / "env/rootfs.sh").read_text()
    assert '"${DOLFINX:-0.9}"' in rootfs                     # 0.9 is the default
    assert '/project/env/install.sh "$release"' in rootfs
    # the expired-Release workaround is for sid only
    assert re.search(r'\[ "\$release" = sid \] && aptopt=', rootfs)


def test_dockerfile_and_rootfs_run_the_same_install_script():
    docker = (ROOT / "Dockerfile").read_text()
    assert re.search(r"^ARG DEBIAN=trixie$", docker, re.M)   # same default as rootfs.sh
    assert re.search(r"^FROM debian:\$\{DEBIAN\}$", docker, re.M)
    assert re.search(r'^RUN sh /tmp/env/install\.sh "\$\{DEBIAN\}"', docker, re.M)
    assert "COPY env/ /tmp/env/" in docker


def test_install_script_reads_one_package_list_per_release():
    install = (ROOT / "env/install.sh").read_text()
    assert 'debian-packages-$release.txt' in install and "pypi-packages.txt" in install
    for debian in releases().values():
        packages = (ROOT / f"env/debian-packages-{debian}.txt").read_text().split()
        for required in ("python3-dolfinx-real", "python3-adios4dolfinx", "python3-petsc4py",
                         "openmpi-bin", "python3-pytest", "python3-pytest-xdist",
                         "python3-pip"):
            assert required in packages, (debian, required)
    assert "python3-scifem" in (ROOT / "env/debian-packages-trixie.txt").read_text().split()


def test_ci_runs_the_readme_test_command_on_every_release():
    readme = (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci/run").read_text()
    assert "make test" in readme and "make demo" in readme
    commands = [line.strip() for line in ci.splitlines()
                if line.strip() and not line.startswith("#") and not line.startswith("set ")
                and not line.startswith("cd ")]
    assert commands == ["make test"]
    makefile = (ROOT / "Makefile").read_text()
    fallback = re.search(r"^RELEASES = .*,([\d. ]+)\)$", makefile, re.M | re.S)
    assert fallback and fallback.group(1).split() == list(releases())
    for target in ("test-serial", "test-mpi", "test-interrupt"):
        assert re.search(rf"DOLFINX=\$\$v \$\(MAKE\) .*{target}", makefile)
    # the serial run's workers (pytest-xdist): what tests/conftest.py schedules
    assert re.search(r"^test-serial:.*\n\t.*-m \"not slow\" -n \$\(JOBS\)", makefile, re.M)


def test_an_mpi_launcher_is_recognised_directly_and_through_rodenv():
    assert starts_mpi(["mpirun", "-n", "2", sys.executable, "-m", "dolfin_rod"])
    assert starts_mpi(["/usr/bin/mpirun", "-n", "3", sys.executable])
    assert starts_mpi([ROOT / "rodenv", "mpiexec", "-n", "2", sys.executable])
    assert starts_mpi("mpirun -n 2 python3 demos/torsion_creep.py")
    assert not starts_mpi([sys.executable, "-m", "dolfin_rod", "run", "mpirun.toml"])
    assert not starts_mpi([sys.executable, "-c", "import subprocess  # mpirun"])


def test_a_test_starting_mpi_waits_for_the_others_and_holds_them_back(tmp_path):
    """Two workers' claims (two open file descriptions: flocks conflict as between two
    processes): the whole waits for a share to end, a new share waits for the whole."""
    first, second = Cores(tmp_path), Cores(tmp_path)
    first.share()
    whole = threading.Thread(target=lambda: (second.share(), second.take_whole()))
    whole.start()
    whole.join(timeout=0.5)
    assert whole.is_alive()                       # the MPI job waits for the running test
    first.release()
    whole.join(timeout=10)
    assert not whole.is_alive() and second.whole
    share = threading.Thread(target=first.share)
    share.start()
    share.join(timeout=0.5)
    assert share.is_alive()                       # the next test waits for the MPI test
    second.release()
    share.join(timeout=10)
    assert not share.is_alive()
    first.release()
    first.close()
    second.close()


def test_the_serial_references_python_answers_and_a_failure_ends_it():
    """The MPI tests' serial references (tests/serial_reference.py): one Python serves
    them in turn; what a request prints does not spoil its answer; a failing request is
    raised with its traceback and ends that Python, and the next request starts anew."""
    assert serial_reference.on_one_process("builtins.print", "a run's output") is None
    first = serial_reference.on_one_process("os.getpid")
    assert serial_reference.on_one_process("math.hypot", 3.0, 4.0) == 5.0
    assert serial_reference.on_one_process("os.getpid") == first    # the same Python
    with pytest.raises(RuntimeError, match=r"math.sqrt(?s:.*)ValueError"):
        serial_reference.on_one_process("math.sqrt", -1.0)
    assert serial_reference.on_one_process("os.getpid") != first    # a new one


def test_pyproject_declares_the_supported_dolfinx_releases():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    dolfinx = [d for d in project["dependencies"] if d.startswith("fenics-dolfinx")]
    assert dolfinx == ["fenics-dolfinx>=0.9,<0.12"]
    assert project["scripts"]["dolfin-rod"] == "dolfin_rod.__main__:main"


def test_environment_has_the_requested_dolfinx():
    import dolfinx

    from dolfin_rod.fem import compat
    version = tuple(int(x) for x in dolfinx.__version__.split(".")[:2])
    assert compat.DOLFINX_VERSION == version
    assert (0, 9) <= version < (0, 12)
    if "DOLFINX" in os.environ:          # set by ./rodenv inside its Debian roots
        assert version == tuple(int(x) for x in os.environ["DOLFINX"].split("."))


def test_two_mpi_test_jobs_from_one_worktree_keep_their_own_logs(tmp_path):
    """tests/mpi_pytest.sh on a rank > 0 of two jobs started from one folder: the job
    that fails prints its own rank's log, not the other job's (before, both wrote
    results/pytest-rank1.log: the second job truncated it and the failing job printed
    the other's tests with its own report's tail); the passing job leaves no log."""
    import subprocess
    import time
    (tmp_path / "test_slow_failure.py").write_text(
        "import time\n\ndef test_fails_late():\n    time.sleep(3)\n    assert False\n")
    (tmp_path / "test_quick_pass.py").write_text("def test_passes():\n    pass\n")
    env = {**os.environ, "OMPI_COMM_WORLD_RANK": "1"}
    script = str(ROOT / "tests" / "mpi_pytest.sh")

    def job(name: str) -> subprocess.Popen:
        return subprocess.Popen([script, "-p", "no:cacheprovider", name], cwd=tmp_path,
                                env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True)
    failing = job("test_slow_failure.py")
    time.sleep(1.0)                         # the failing job's pytest has started its log
    passing = job("test_quick_pass.py")
    assert passing.wait(timeout=120) == 0
    _, said = failing.communicate(timeout=120)
    assert failing.returncode == 1
    assert "test_fails_late" in said and "test_quick_pass" not in said, said
    assert [p.name for p in (tmp_path / "results").iterdir()] == \
        [p.name for p in (tmp_path / "results").glob("pytest-rank1.*.log")]
    assert len(list((tmp_path / "results").iterdir())) == 1      # the failing job's
