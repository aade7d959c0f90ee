#!/bin/sh
# Installs the dolfin_rod environment into a Debian system, as root:
#   sh env/install.sh trixie    DOLFINx 0.9  (env/debian-packages-trixie.txt; the default)
#   sh env/install.sh sid       DOLFINx 0.11 (env/debian-packages-sid.txt)
# Called by the Dockerfile and, inside a bubblewrap sandbox, by env/rootfs.sh:
# one script, so the container and the no-Docker path are the same environment.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
release=${1:-trixie}
packages="$here/debian-packages-$release.txt"
[ -f "$packages" ] || { echo "install.sh: no package list for Debian '$release'" >&2; exit 1; }
export DEBIAN_FRONTEND=noninteractive
# sid's Release file on the reachable mirrors can be past its Valid-Until date; the
# rolling release is only ever installed as it is now, so do not insist on freshness.
aptopt=""
[ "$release" = sid ] && aptopt="-o Acquire::Check-Valid-Until=false"
# shellcheck disable=SC2086
apt-get $aptopt update -q
# shellcheck disable=SC2046
apt-get install -y -q --no-install-recommends $(grep -v '^#' "$packages")
command -v update-ca-certificates >/dev/null && update-ca-certificates >/dev/null
apt-get clean
rm -rf /var/lib/apt/lists/*
# PyPI-only packages, without dependencies so that Debian's numpy/petsc4py stay in charge.
grep -v '^#' "$here/pypi-packages.txt" | xargs -r pip install --no-deps --break-system-packages --root-user-action=ignore -q
