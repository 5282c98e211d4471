# The two commands of README.md. Each creates the virtual environment and installs
# calflow with its dependencies on first use, so it works on a fresh machine.
PYTHON ?= python3
VENV   ?= .venv
CORES  ?= 2
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.calflow-installed

.PHONY: run test dry-run lint clean

$(STAMP): pyproject.toml plugins/calflow-hexapod/pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	$(BIN)/python -m pip install --quiet -e plugins/calflow-hexapod  # the hexapod family's own distribution
	touch $(STAMP)

run: $(STAMP)  ## run the default campaigns and write reports/
	$(BIN)/snakemake --cores $(CORES)

test: $(STAMP)  ## run the test suite (calflow's, then the hexapod plug-in's own)
	$(BIN)/python -m pytest -n $(CORES) --dist loadfile
	cd plugins/calflow-hexapod && $(abspath $(BIN))/python -m pytest -n $(CORES) --dist loadfile

dry-run: $(STAMP)
	$(BIN)/snakemake --cores $(CORES) -n

clean:
	rm -rf results reports .snakemake
