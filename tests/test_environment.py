"""The two ways into the environment share one install script and one package list."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_dockerfile_and_rootfs_run_the_same_install_script():
    docker = (ROOT / "Dockerfile").read_text()
    rootfs = (ROOT / "env/rootfs.sh").read_text()
    assert re.search(r"^FROM debian:trixie\b", docker, re.M)
    assert re.search(r"^RUN sh /tmp/env/install\.sh", docker, re.M)
    assert "COPY env/ /tmp/env/" in docker
    assert "/project/env/install.sh" in rootfs
    assert "trixie" in rootfs


def test_install_script_reads_the_package_lists():
    install = (ROOT / "env/install.sh").read_text()
    assert "debian-packages.txt" in install and "pypi-packages.txt" in install
    packages = (ROOT / "env/debian-packages.txt").read_text().split()
    for required in ("python3-dolfinx-real", "python3-scifem", "python3-adios4dolfinx",
                     "openmpi-bin", "python3-pytest"):
        assert required in packages


def test_ci_runs_the_readme_test_command():
    readme = (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci/run").read_text()
    assert "make test" in readme and "make demo" in readme
    commands = [line.strip() for line in ci.splitlines()
                if line.strip() and not line.startswith("#") and not line.startswith("set ")
                and not line.startswith("cd ")]
    assert commands == ["make test"]


def test_environment_has_dolfinx_0_9():
    import dolfinx
    import scifem  # noqa: F401
    assert tuple(int(x) for x in dolfinx.__version__.split(".")[:2]) >= (0, 9)
