#!/usr/bin/env bash
# Workflow benchmarks: cold run of the default campaigns, a no-op rerun, and a rerun
# after a validation-only change of one campaign, in a scratch copy of the project.
#   bash benchmarks/bench_workflow.sh [CORES]
# (the Monte-Carlo study is part of the default run; CLI start-up and snakemake --report last)
set -euo pipefail
cores="${1:-2}"
root="$(cd "$(dirname "$0")/.." && pwd)"
snakemake="$root/.venv/bin/snakemake"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cp -r "$root/Snakefile" "$root/workflow" "$root/config" "$work/"
cd "$work"
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores; --cores $cores"
t() { local s; s=$(date +%s.%N); "$@" > /dev/null 2>&1; python3 -c "print(round($(date +%s.%N) - $s, 1))"; }
echo "cold run of the default campaigns: $(t "$snakemake" --cores "$cores") s"
echo "no-op rerun: $(t "$snakemake" --cores "$cores") s"
sed -i 's/^  cycles: 30 .*/  cycles: 20/' config/campaigns/xytheta-thesis.yaml
jobs=$("$snakemake" -n --quiet rules --cores "$cores" 2>&1 | awk '/^[a-z_]+ +[0-9]+$/ && !seen[$1]++ {printf "%s=%s ", $1, $2}')
echo "validation-only change of xytheta-thesis would run: $jobs"
echo "rerun after it: $(t "$snakemake" --cores "$cores") s"
calflow="$root/.venv/bin/calflow"
best=$(for i in 1 2 3 4 5; do t "$calflow" --help; done | sort -n | head -1)
echo "calflow --help (best of 5): $best s"
echo "snakemake --report report.zip: $(t "$snakemake" --report "$work/report.zip") s"
