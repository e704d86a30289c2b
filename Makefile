# cosserat-fem: every target sets itself up first (apt packages, .venv, editable install)
# through the one set-up script, .ci/setup.sh, which is idempotent and fast when done.
SHELL := /bin/bash
VENV ?= .venv
PY := $(VENV)/bin/python
# Open MPI refuses to run as root unless told; containers and CI run as root.
export OMPI_ALLOW_RUN_AS_ROOT := 1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM := 1
export OMPI_MCA_rmaps_base_oversubscribe := 1
# A rank that waits for another yields its core instead of spinning on it, and no rank is bound
# to one core: on a machine busy with other work (or two mpirun jobs at once) the ranks share
# the cores with it (docs/developers.md, "Tests on a busy machine").
export OMPI_MCA_mpi_yield_when_idle := 1
export OMPI_MCA_hwloc_base_binding_policy := none

.PHONY: setup demo demo-response demo-rom demo-structure demo-contact test test-long unit lint format verify bench clean container-test

setup:
	@VENV=$(VENV) bash .ci/setup.sh

## The main job: the paper's cantilever (Figs. 4-6), outputs in demos/output/.
demo: setup
	$(PY) demos/cao_tucker_2008.py

## The second demo: a frequency response with jumps (a sweep; two chains on two ranks).
demo-response: setup
	OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 mpirun -n 2 $(PY) demos/frequency_response.py

## The third demo: a forcing-frequency sweep over the first two resonances, reduced members
## (POD, Galerkin) beside full ones (two ranks; ROM_MEMBERS=201 for the issue's size).
demo-rom: setup
	OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 COSSERAT_ROM_SWEEP_MEMBERS=$(or $(ROM_MEMBERS),21) mpirun -n 2 $(PY) demos/rom_frequency_sweep.py

## The fourth demo: a branched cable (a structure of three rods) swinging under gravity.
demo-structure: setup
	OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 mpirun -n 2 $(PY) demos/branched_cable.py

## The fifth demo: the capstan, a rope held on a fixed drum by Coulomb friction (contact).
demo-contact: setup
	OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 mpirun -n 2 $(PY) demos/capstan.py

## Lint, then the test suite (serial and mpirun -n 2 cases) without the long set, its files
## dealt to one pytest worker per core (pytest-xdist; a file's tests share its fixtures).
test: setup lint
	$(PY) -m pytest -q -n auto --dist loadfile -m "not long" tests

## The long set (pytest -m long): stress cases, kills and restarts, ParaView and rendering,
## killed compiles. CI runs it after make test (.ci/run).
test-long: setup
	$(PY) -m pytest -q -m long tests

## The unit tests alone, tests/unit/<subpackage>/test_<module>.py a module (integrators, Newton
## stop rule, step controller, charts, keys, expressions, readers, errors): about 5 CPU seconds. How long each target takes, and on what machine: README, "How long it takes".
unit: setup
	$(PY) -m pytest -q tests/unit

## Regenerate docs/verification.md (modes, large deflections, orders, energy, rotations, curved
## rods, responses; 251 s of wall time on the 2-core development machine, 2026-12-02).
verify: setup
	$(PY) benchmarks/verify.py

## Work-precision benchmark against PyElastica (benchmarks/results/; about 25 minutes of wall
## time on the 2-core development machine, 2026-12-01).
bench: setup
	$(PY) benchmarks/work_precision.py

## Build the Dockerfile (docker, or rootful podman) and run make test and the MPI demo in it.
container-test:
	bash .ci/container-test.sh

## ruff's linter and formatter (check only), then the type checker over the package and forms/
## (pyproject.toml's [tool.mypy]). `make format` formats the tree in place.
lint: setup
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	$(VENV)/bin/mypy

format: setup
	$(VENV)/bin/ruff format .
	$(VENV)/bin/ruff check --fix .

clean:
	rm -rf demos/output results .pytest_cache .ruff_cache .mypy_cache
