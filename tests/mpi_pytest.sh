#!/bin/sh
# pytest on every rank of an MPI job (make test-mpi): rank 0 reports; the other ranks
# log to results/pytest-rank<N>.log, which is printed if that rank fails.
rank=${OMPI_COMM_WORLD_RANK:-${PMI_RANK:-0}}
[ "$rank" = 0 ] && exec python3 -m pytest "$@"
mkdir -p results
log="results/pytest-rank$rank.log"
python3 -m pytest "$@" >"$log" 2>&1 || { status=$?; cat "$log" >&2; exit "$status"; }
