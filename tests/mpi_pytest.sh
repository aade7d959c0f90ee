#!/bin/sh
# pytest on every rank of an MPI job (make test-mpi): rank 0 reports; the other ranks
# log to a file of their own, results/pytest-rank<N>.<unique>.log (two jobs started from
# one worktree must not write one file), printed and kept if that rank fails, removed
# if it passes.
rank=${OMPI_COMM_WORLD_RANK:-${PMI_RANK:-0}}
[ "$rank" = 0 ] && exec python3 -m pytest "$@"
mkdir -p results
log=$(mktemp "results/pytest-rank$rank.XXXXXX.log") || exit 1
python3 -m pytest "$@" >"$log" 2>&1 || {
    status=$?; cat "$log" >&2; echo "(rank $rank's log: $log)" >&2; exit "$status"; }
rm -f "$log"
