# The two commands of README.md. Each creates the virtual environment and installs
# calflow with the versions the suite passed with (requirements/lock.txt) on first use, so it
# works on a fresh machine. docs/development.md: lint, the lock and how to upgrade it.
PYTHON ?= python3
VENV   ?= .venv
CORES  ?= 2
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.calflow-installed
LOCK   := requirements/lock.txt
# what ruff checks (plugins/ when there is one)
LINTED := $(wildcard src tests benchmarks plugins)
# `make lock LOCK_FLAGS=--upgrade`: every package to its newest release that fits
LOCK_FLAGS ?=

.PHONY: run test test-fast bench-smoke cluster-test cluster-study dry-run lint lock browser clean

# Python writes each module's bytecode (.pyc) the first time a process imports it, in the
# recipes below even where the caller's shell sets PYTHONDONTWRITEBYTECODE (this machine's
# shells, many CI images): otherwise no process ever writes one, and every process of the
# suite — each workflow job among them — compiles xarray, scipy and pandas again. So the lock is
# installed without pip's byte-compiling (~9500 modules, ~25 s of a fresh install): what the
# runs import is compiled once, when first imported (docs/development.md, "The lock").
unexport PYTHONDONTWRITEBYTECODE

$(STAMP): pyproject.toml plugins/calflow-hexapod/pyproject.toml $(LOCK)
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet --no-compile -r $(LOCK)
	$(BIN)/python -m pip install --quiet --no-deps -e . -e plugins/calflow-hexapod
	@$(BIN)/python -m pip check >/dev/null || { $(BIN)/python -m pip check; \
	  echo "$(LOCK) does not hold what pyproject.toml asks for: run 'make lock'"; exit 1; }
	touch $(STAMP)

run: $(STAMP)  ## run the default campaigns and write reports/
	$(BIN)/snakemake --cores $(CORES)

test: $(STAMP) browser  ## run the test suite (calflow's, then the hexapod plug-in's own)
	$(BIN)/python -m pytest -n $(CORES) --dist loadfile
	cd plugins/calflow-hexapod && $(abspath $(BIN))/python -m pytest -n $(CORES) --dist loadfile

test-fast: $(STAMP)  ## the unit and property tests only (no workflow run, no process killed): about a minute
	$(BIN)/python -m pytest -n $(CORES) --dist loadfile -m "not workflow and not process" -q

bench-smoke: $(STAMP)  ## every benchmark of benchmarks/ at its small --smoke size, so none rots unseen
	$(BIN)/python benchmarks/smoke.py

cluster-test: $(STAMP)  ## as root: a one-node SLURM cluster runs the workflow, compared with a local run
	VENV=$(VENV) bash tests/cluster/run.sh

cluster-study: $(STAMP)  ## as root: the 2048-point Monte-Carlo study through the one-node cluster and locally
	VENV=$(VENV) bash tests/cluster/run.sh --studies montecarlo-xytheta-cluster --no-faults \
		--target reports/studies/montecarlo-xytheta-cluster.html --max-slurm-jobs 100

dry-run: $(STAMP)
	$(BIN)/snakemake --cores $(CORES) -n

lint: $(STAMP)  ## style: ruff (lint and format) and snakefmt, checked, nothing changed
	$(BIN)/ruff check $(LINTED)
	$(BIN)/ruff format --check $(LINTED)
	$(BIN)/snakefmt --check Snakefile workflow src/calflow/*/rules $(wildcard plugins/*/src/*/rules)

lock: $(STAMP)  ## resolve requirements/lock.txt again from pyproject.toml, on PyPI
	PIP_CONFIG_FILE=/dev/null CUSTOM_COMPILE_COMMAND="make lock" $(BIN)/pip-compile --quiet $(LOCK_FLAGS) --extra test --extra cluster \
	  --strip-extras --no-emit-index-url --no-emit-find-links --output-file $(LOCK) pyproject.toml

browser:  ## headless Chromium for the report test, from the system's packages (Debian's chromium)
	@command -v chromium >/dev/null || command -v chromium-browser >/dev/null || { \
	  if [ "$$(id -u)" = 0 ]; then SUDO=; else SUDO=sudo; fi; \
	  $$SUDO apt-get update -q && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -q chromium; }

clean:
	rm -rf results reports .snakemake
