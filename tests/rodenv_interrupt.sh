#!/bin/bash
# Ctrl-C through ./rodenv (issue 13 item 9), as a user meets it: SIGINT to the process
# group of `./rodenv dolfin-rod run SCENE`, on the host (bubblewrap) or natively.
#   mid-run:     exit status 130 (dolfin_rod.cli), summary.json says "interrupted",
#                the time series is kept
#   start-up:    exit status 130, no Python traceback
#   SIGTERM to ./rodenv mid-run, and Ctrl-C and SIGTERM under `./rodenv mpirun -n 2`
#   (issue 28 item 22): the same as Ctrl-C mid-run
#   SIGKILL to ./rodenv mid-run: the command ends with it (it went on writing its folder)
# Run by `make test` for each release (DOLFINX=0.9|0.11); the first run also compiles
# the scene's forms, so the start-up case does not interrupt a compiler.
set -euo pipefail
cd "$(dirname "$0")/.."
work="results/interrupt-test-${DOLFINX:-0.9}"
rm -rf "$work"
mkdir -p "$work"
# The torsion PDE model of the creep scene, with a horizon it would need hours for.
sed -e 's/^name = .*/name = "interrupt"\nmodel = "torsion"/' -e 's/^t_end = .*/t_end = 1e5/' \
    scenes/torsion_creep.toml >"$work/scene.toml"

fail() { echo "rodenv_interrupt: FAIL: $*" >&2; exit 1; }

# Job control: each background job gets a process group of its own (pid = group id) and,
# as in a terminal, SIGINT at its default (without it, a background job ignores SIGINT).
set -m
start() {  # start NAME [LAUNCHER...]
    name=$1; shift
    ./rodenv "$@" dolfin-rod run "$work/scene.toml" --out "$work/$name" >"$work/$name.out" \
        2>"$work/$name.err" &
    pid=$!
}

wait_for() {  # wait_for DESCRIPTION TEST...: poll TEST for up to 5 minutes
    what=$1; shift
    i=0
    until "$@"; do
        i=$((i + 1))
        kill -0 "$pid" 2>/dev/null || { cat "$work"/*.err >&2; fail "run ended before $what"; }
        [ "$i" -lt 1500 ] || { kill -KILL -- "-$pid"; fail "no $what in 5 minutes"; }
        sleep 0.2
    done
}

interrupt() {  # SIGINT to the whole group, as Ctrl-C does; status is the run's exit status
    kill -INT -- "-$pid"
    status=0
    wait "$pid" || status=$?
}

terminate() {  # SIGTERM to ./rodenv, as kill or a batch system does
    kill -TERM "$pid"
    status=0
    wait "$pid" || status=$?
}

mid_run() {  # mid_run NAME SIGNAL-FUNCTION [LAUNCHER...]
    name=$1 how=$2; shift 2
    rows() { [ "$(cat "$work/$name/timeseries.csv" 2>/dev/null | wc -l)" -ge 20 ]; }
    start "$name" "$@"
    wait_for "20 steps" rows
    "$how"
    [ "$status" = 130 ] || { cat "$work/$name.err" >&2; fail "$name: exit status $status, not 130"; }
    grep -q '"status": *"interrupted"' "$work/$name/summary.json" \
        || fail "$name: summary.json missing or not 'interrupted'"
    grep -qi 'interrupted' "$work/$name.out" "$work/$name.err" \
        || fail "$name: no 'interrupted' message"
}
mid_run run interrupt
mid_run term terminate
mid_run mpi-int interrupt mpirun -n 2
mid_run mpi-term terminate mpirun -n 2

# kill -9 of ./rodenv: no trap sees it; the run must not go on writing its folder
start killed
rows() { [ "$(cat "$work/killed/timeseries.csv" 2>/dev/null | wc -l)" -ge 20 ]; }
wait_for "20 steps" rows
kill -KILL "$pid"
wait "$pid" || true
sleep 3
before=$(wc -l <"$work/killed/timeseries.csv")
sleep 3
[ "$(wc -l <"$work/killed/timeseries.csv")" = "$before" ] \
    || fail "killed: the run went on writing after ./rodenv was SIGKILLed"
! pgrep -f "$work/killed" >/dev/null || fail "killed: the run is still alive"

started() { grep -q '^model: ' "$work/startup.out"; }
start startup
wait_for "start-up message" started
interrupt
[ "$status" = 130 ] || { cat "$work/startup.err" >&2; fail "start-up: exit status $status"; }
! grep -q Traceback "$work/startup.err" || { cat "$work/startup.err" >&2; fail "start-up: traceback"; }
echo "rodenv_interrupt: OK (mid-run and start-up Ctrl-C, SIGTERM, both under mpirun -n 2:" \
    "exit status 130, summary written; SIGKILL: the run ends with ./rodenv)"
