#!/bin/sh
# Builds (once) and prints the path of the Debian root file system in which dolfin_rod
# runs on hosts without DOLFINx.  Used by ./rodenv.  The release follows $DOLFINX:
#   DOLFINX=0.9   Debian trixie (the default)
#   DOLFINX=0.11  Debian sid
#
#   env/rootfs.sh path     print the root's path, building it first if needed
#   env/rootfs.sh build    build it (no-op when complete)
#
# The root is built into "<dir>.partial", provisioned with env/install.sh (the script
# the Dockerfile runs) and only then moved to "<dir>": an interrupted or failed build is
# never mistaken for a good one.  Its name carries a hash of the package lists and the
# install script, so editing them builds a fresh root.
set -eu
env_dir=$(cd "$(dirname "$0")" && pwd)
project=$(dirname "$env_dir")
cache=${DOLFIN_ROD_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/dolfin_rod}
need_mb=4000

case "${DOLFINX:-0.9}" in
    0.9) release=trixie ;;
    0.11) release=sid ;;
    *) printf 'rodenv: error: DOLFINX=%s is not supported (use 0.9 or 0.11)\n' "$DOLFINX" >&2
       exit 2 ;;
esac
# sid's Release file on the reachable mirrors can be past its Valid-Until date.
aptopt=""
[ "$release" = sid ] && aptopt='Acquire::Check-Valid-Until "false"'

say() { printf 'rodenv: %s\n' "$*" >&2; }
die() { say "error: $*"; exit 1; }

hash=$(cat "$env_dir/debian-packages-$release.txt" "$env_dir/pypi-packages.txt" \
       "$env_dir/install.sh" | sha256sum | cut -c1-12)
root="$cache/$release-$hash"

host_tools() {
    missing=""
    command -v mmdebstrap >/dev/null 2>&1 || missing="$missing mmdebstrap"
    command -v bwrap >/dev/null 2>&1 || missing="$missing bubblewrap"
    [ -z "$missing" ] && return 0
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
        say "installing host tools:$missing (apt-get)"
        { apt-get update -q && apt-get install -y -q $missing; } >&2 \
            || die "could not install$missing with apt-get; install them by hand:" \
                   "apt-get install$missing"
    else
        die "missing host tools:$missing.  Install them (as root): apt-get install$missing"
    fi
}

check_disk() {
    mkdir -p "$cache"
    avail=$(df -Pm "$cache" | awk 'NR==2 {print $4}')
    [ "$avail" -ge "$need_mb" ] || die "only ${avail} MB free under $cache; the" \
        "environment needs about ${need_mb} MB.  Free space or set DOLFIN_ROD_CACHE" \
        "to a larger disk."
}

sandbox() {  # sandbox ROOT CMD...: run CMD as root inside ROOT with the project at /project
    r=$1; shift
    bwrap --bind "$r" / --bind "$project" /project --ro-bind /sys /sys --proc /proc \
        --dev /dev --perms 01777 --tmpfs /tmp --ro-bind /etc/resolv.conf /etc/resolv.conf \
        --clearenv --setenv HOME /root --setenv LANG C.UTF-8 \
        ${http_proxy:+--setenv http_proxy "$http_proxy"} \
        ${https_proxy:+--setenv https_proxy "$https_proxy"} \
        --setenv PATH /usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin \
        --chdir /project "$@"
}

build() {
    [ -f "$root/.dolfin_rod-complete" ] && return 0
    mkdir -p "$cache"
    exec 8>"$cache/.lock-host-tools"
    flock 8   # two first builds at once (0.9 and 0.11): one apt-get at a time
    host_tools
    flock -u 8
    check_disk
    exec 9>"$cache/.lock-$release"
    flock 9   # a second rodenv waits for the first build instead of racing it
    [ -f "$root/.dolfin_rod-complete" ] && return 0
    partial="$root.partial"
    rm -rf "$partial"
    say "building the DOLFINx ${DOLFINX:-0.9} environment (Debian $release) in $root"
    say "first use only: about 3 minutes and 2.5 GB; later calls start at once"
    log="$cache/build-$hash.log"
    mmdebstrap --variant=apt --include=ca-certificates ${aptopt:+--aptopt="$aptopt"} \
        "$release" "$partial" >"$log" 2>&1 \
        || die "mmdebstrap failed (is the Debian archive reachable?  see $log)"
    # Certificate authorities the host added (a proxy's, a company's) are trusted inside too.
    for ca in /usr/local/share/ca-certificates/*.crt; do
        [ -f "$ca" ] && cp "$ca" "$partial/usr/local/share/ca-certificates/"
    done
    sandbox "$partial" /bin/sh /project/env/install.sh "$release" >>"$log" 2>&1 \
        || die "env/install.sh failed inside the new root (network?  see $log)"
    touch "$partial/.dolfin_rod-complete"
    rm -rf "$root"
    mv "$partial" "$root"
    say "environment ready ($root)"
}

case "${1:-path}" in
    path) build; printf '%s\n' "$root" ;;
    build) build ;;
    *) die "unknown command '$1' (use: path | build)" ;;
esac
