#!/usr/bin/env bash
# `make cluster-test`: install what the cluster test needs, start the one-node SLURM cluster,
# run tests/cluster/run_cluster.py, and stop every daemon started here, also on failure or
# interruption. Arguments go to run_cluster.py (e.g. --campaigns nano2d-thesis --studies).
set -euo pipefail
cd "$(dirname "$0")/../.."
VENV="${VENV:-.venv}"
start=$(date +%s)
bash tests/cluster/cluster.sh install
# the executor plugin at the version this test ran with (pyproject.toml, extra `cluster`)
"$VENV/bin/python" -m pip install --quiet -e '.[cluster]'
trap 'bash tests/cluster/cluster.sh stop' EXIT
trap 'exit 130' INT TERM
bash tests/cluster/cluster.sh start
"$VENV/bin/python" tests/cluster/run_cluster.py "$@"
echo "cluster-test: $(( $(date +%s) - start )) s including installs and cluster start" >&2
