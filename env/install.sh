#!/bin/sh
# Installs the dolfin_rod environment into a Debian trixie system, as root.
# Called by the Dockerfile and, inside a bubblewrap sandbox, by env/rootfs.sh:
# one script, so the container and the no-Docker path are the same environment.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
export DEBIAN_FRONTEND=noninteractive
apt-get update -q
# shellcheck disable=SC2046
apt-get install -y -q --no-install-recommends $(grep -v '^#' "$here/debian-packages.txt")
command -v update-ca-certificates >/dev/null && update-ca-certificates >/dev/null
apt-get clean
rm -rf /var/lib/apt/lists/*
# PyPI-only packages, without dependencies so that Debian's numpy/petsc4py stay in charge.
grep -v '^#' "$here/pypi-packages.txt" | xargs -r pip install --no-deps --break-system-packages --root-user-action=ignore -q
