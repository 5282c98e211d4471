#!/usr/bin/env bash
# Submit a Snakemake job script as a detached background process; print its id.
# The job script writes its own finished/failed markers (cluster-generic without a
# status command), so nothing else is needed here.
set -euo pipefail
jobscript="${!#}"
mkdir -p .snakemake/local-cluster
log=".snakemake/local-cluster/$(basename "$jobscript").log"
nohup bash "$jobscript" > "$log" 2>&1 < /dev/null &
echo "$!"
