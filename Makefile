# The two commands of README.md. Each creates the virtual environment and installs
# calflow with its dependencies on first use, so it works on a fresh machine.
PYTHON ?= python3
VENV   ?= .venv
CORES  ?= 2
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.calflow-installed

.PHONY: run test cluster-test cluster-study dry-run lint clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

run: $(STAMP)  ## run the default campaigns and write reports/
	$(BIN)/snakemake --cores $(CORES)

test: $(STAMP)  ## run the test suite
	$(BIN)/python -m pytest -n $(CORES) --dist loadfile

cluster-test: $(STAMP)  ## as root: a one-node SLURM cluster runs the workflow, compared with a local run
	VENV=$(VENV) bash tests/cluster/run.sh

cluster-study: $(STAMP)  ## as root: the 2048-point Monte-Carlo study through the one-node cluster and locally
	VENV=$(VENV) bash tests/cluster/run.sh --studies montecarlo-xytheta-cluster --no-faults \
		--target reports/studies/montecarlo-xytheta-cluster.html --max-slurm-jobs 100

dry-run: $(STAMP)
	$(BIN)/snakemake --cores $(CORES) -n

clean:
	rm -rf results reports .snakemake
