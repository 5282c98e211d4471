#!/usr/bin/env bash
# `make cluster-test`: install what the cluster test needs, start the one-node SLURM cluster,
# run tests/cluster/run_cluster.py, and stop every daemon started here, also on failure or
# interruption. Arguments go to run_cluster.py (e.g. --campaigns nano2d-thesis --studies).
set -euo pipefail
cd "$(dirname "$0")/../.."
VENV="${VENV:-.venv}"
start=$(date +%s)
bash tests/cluster/cluster.sh install
# the SLURM executor plugin at the version pinned in pyproject.toml's extra `cluster` (the
# rest of the environment stays as requirements/lock.txt made it)
plugin="$("$VENV/bin/python" -c 'import tomllib; deps = tomllib.load(open("pyproject.toml", "rb"))["project"]["optional-dependencies"]["cluster"]; print(next(d for d in deps if "plugin-slurm" in d))')"
"$VENV/bin/python" -m pip install --quiet "$plugin"
child=""
cleanup() {
    # the test first (it ends its Snakemake runs), then the jobs and the daemons
    if [[ -n "$child" ]] && kill -0 "$child" 2>/dev/null; then
        kill -TERM "$child" 2>/dev/null || true
        wait "$child" 2>/dev/null || true
    fi
    bash tests/cluster/cluster.sh stop
}
trap cleanup EXIT
trap 'exit 130' INT TERM
bash tests/cluster/cluster.sh start
# in the background and waited for, so that a signal to this script runs the trap at once
"$VENV/bin/python" tests/cluster/run_cluster.py "$@" &
child=$!
wait "$child"
echo "cluster-test: $(( $(date +%s) - start )) s including installs and cluster start" >&2
