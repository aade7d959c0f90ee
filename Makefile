# Every target runs inside the dolfin_rod environment through ./rodenv, which builds
# that environment on first use (see README.md, "Environment").  DOLFINX=0.9 (default,
# Debian trixie) or DOLFINX=0.11 (Debian sid) chooses the release.
RODENV  := ./rodenv
PYTEST  := python3 -m pytest
NP      ?= 2
# the serial run's pytest-xdist workers: one per core (JOBS=0: one process, no workers)
JOBS    ?= auto
# `make test` covers: DOLFINX if set; else the host's own DOLFINx if python3 imports one
# (the Docker image, conda; ./rodenv then runs natively); else both releases.
RELEASES = $(or $(DOLFINX),$(shell python3 -c 'import dolfinx; \
    print(".".join(dolfinx.__version__.split(".")[:2]))' 2>/dev/null),0.9 0.11)

.PHONY: demo demos test test-serial test-mpi test-interrupt test-paths test-long bench work-precision stability env shell clean

demo:            ## the flagship demo: viscoelastic cantilever creep and recovery (results/)
	$(RODENV) python3 demos/cantilever_creep.py

demos:           ## every demo as a user runs it, serially and under mpirun
	$(RODENV) $(PYTEST) tests/test_demos.py -m "slow or not slow"

test:            ## the CI suite on each release: serial run, then the MPI run on $(NP) ranks
	@for v in $(RELEASES); do \
	    echo "== DOLFINx $$v: make test-serial test-mpi test-interrupt test-paths"; \
	    DOLFINX=$$v $(MAKE) --no-print-directory test-serial test-mpi test-interrupt \
	        test-paths \
	        || exit 1; \
	done

test-serial:     ## the default tests, one worker per core (an MPI job of a test: tests/conftest.py)
	$(RODENV) $(PYTEST) -m "not slow" -n $(JOBS) --dist worksteal

test-mpi:
	$(RODENV) mpirun -n $(NP) tests/mpi_pytest.sh -m "mpi and not slow"

test-interrupt:  ## Ctrl-C through ./rodenv: dolfin-rod stops, writes its summary, exits 130
	tests/rodenv_interrupt.sh

test-paths:      ## ./rodenv sees and writes the user's paths (outside the project, /tmp)
	tests/rodenv_paths.sh

test-long:       ## long verification runs (convergence studies, long horizons)
	$(RODENV) $(PYTEST) -m slow

bench:           ## performance benchmarks: JSON and PNG under results/bench/
	$(RODENV) python3 benchmarks/run_all.py

work-precision:  ## the speed-accuracy chart of the integrators
	$(RODENV) python3 demos/work_precision.py

stability:       ## the stability study of the integrators (docs/stability.md)
	$(RODENV) python3 demos/stability_study.py

env:             ## build the environment now (make test/demo do it on first use)
	$(RODENV) python3 -c "import dolfinx, dolfin_rod; print('DOLFINx', dolfinx.__version__)"

shell:
	$(RODENV) bash

clean:
	rm -rf results .pytest_cache
