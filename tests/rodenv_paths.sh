#!/bin/bash
# The user's paths through ./rodenv (issue 28 item 1), as a user meets them on the host:
#   a scene outside the project, --out in the host's /tmp (the sandbox has a private
#   /tmp), relative paths from a folder outside the project, --out into a folder that
#   does not exist yet, --overwrite of a run folder there: the results are on this
#   machine where the user said;
#   --out inside the environment's system folders: exit 2, a message naming what it can
#   reach, nothing written into the environment's root.
# Run by `make test` for each release (DOLFINX=0.9|0.11).
set -euo pipefail
project=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d /tmp/rodenv-paths.XXXXXX)
trap 'rm -rf "$work" "$work-new"' EXIT
fail() { echo "rodenv_paths: FAIL: $*" >&2; exit 1; }

mkdir -p "$work/my scenes"
# the ODE model of torsion relaxation, two steps: seconds, no FE compilation
sed -e 's/^t_end = .*/t_end = 0.02/' "$project/scenes/torsion_relaxation.toml" \
    >"$work/my scenes/relax.toml"

completed() {  # completed FOLDER: a finished run folder on the host
    grep -q '"status": *"completed"' "$1/summary.json" 2>/dev/null \
        || fail "no completed summary.json in $1 on the host"
}

# absolute paths outside the project, the results in the host's /tmp
"$project/rodenv" dolfin-rod run "$work/my scenes/relax.toml" --out "$work/abs" --quiet \
    || fail "absolute paths: exit status $?"
completed "$work/abs"
# the same --out again with --overwrite: the folder itself is replaced (./rodenv mounts
# its parent; a mounted folder cannot be removed: "Device or resource busy")
"$project/rodenv" dolfin-rod run "$work/my scenes/relax.toml" --out "$work/abs" \
    --overwrite --quiet || fail "--out DIR --overwrite of a run folder: exit status $?"
completed "$work/abs"

# relative paths from a folder outside the project; --out=VALUE; a folder not yet there
(cd "$work" && "$project/rodenv" dolfin-rod run "my scenes/relax.toml" --out=rel/run \
    --quiet) || fail "relative paths: exit status $?"
completed "$work/rel/run"
"$project/rodenv" dolfin-rod run "$work/my scenes/relax.toml" --out "$work-new/x" --quiet \
    || fail "new folder in /tmp: exit status $?"
completed "$work-new/x"

# --out in the environment's own system folders: refused before anything runs (only in
# the sandbox: natively, /usr/local is this machine's)
if [ "${DOLFIN_ROD_SANDBOX:-auto}" != always ] && python3 -c "import dolfinx" 2>/dev/null
then
    echo "rodenv_paths: OK (native DOLFINx: scene outside the project, --out in /tmp," \
        "relative paths)"
    exit 0
fi
root=$("$project/env/rootfs.sh" path)
status=0
"$project/rodenv" dolfin-rod run "$work/my scenes/relax.toml" --out /usr/local/rodenv-paths \
    2>"$work/err" || status=$?
[ "$status" = 2 ] || fail "--out /usr/local/...: exit status $status, not 2"
grep -q "rodenv: --out /usr/local/rodenv-paths .*are reachable" "$work/err" \
    || fail "--out /usr/local/...: message: $(cat "$work/err")"
[ ! -e "$root/usr/local/rodenv-paths" ] || fail "written into the environment's root"
echo "rodenv_paths: OK (scene outside the project, --out in /tmp, relative paths," \
    "system folders refused)"
