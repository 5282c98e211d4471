#!/usr/bin/env bash
# Workflow benchmarks: cold run of the default campaigns, a no-op rerun, and a rerun
# after a validation-only change of one campaign, in a scratch copy of the project.
#   bash benchmarks/bench_workflow.sh [CORES] [REPEATS]
# Each figure is the best of REPEATS (default 3) — on a shared machine the best is the
# one least disturbed by the other work, and the load average is printed beside it. The
# cold run also reports the CPU time of Snakemake and all its jobs (/usr/bin/time, user +
# sys), which other work on the machine disturbs much less than wall time.
# (the Monte-Carlo study is part of the default run; CLI start-up and snakemake --report last)
set -euo pipefail
cores="${1:-2}"
repeats="${2:-3}"
root="$(cd "$(dirname "$0")/.." && pwd)"
snakemake="$root/.venv/bin/snakemake"
calflow="$root/.venv/bin/calflow"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores; --cores $cores; best of $repeats"
t() { local s; s=$(date +%s.%N); "$@" > /dev/null 2>&1; python3 -c "print(round($(date +%s.%N) - $s, 1))"; }
best() { sort -n | head -1; }
load() { cut -d' ' -f1 /proc/loadavg; }
fresh() {  # a scratch project with no results
    rm -rf "$work/p"; mkdir "$work/p"
    cp -r "$root/Snakefile" "$root/workflow" "$root/config" "$work/p/"
}
cold=(); for i in $(seq "$repeats"); do
    fresh; l=$(load); cd "$work/p"
    /usr/bin/time -o "$work/time.txt" -f '%e %U %S' "$snakemake" --cores "$cores" > /dev/null 2>&1
    read -r wall user sys < "$work/time.txt"; cold+=("$wall")
    echo "  cold run $i: $wall s wall, $(python3 -c "print(round($user + $sys))") s CPU (load average before: $l)"
done
echo "cold run of the default campaigns: $(printf '%s\n' "${cold[@]}" | best) s"
cd "$work/p"
echo "no-op rerun: $(for i in $(seq "$repeats"); do t "$snakemake" --cores "$cores"; done | best) s"
cp config/campaigns/xytheta-thesis.yaml "$work/xytheta-thesis.yaml"
jobs=""; change=()
for i in $(seq "$repeats"); do  # alternate the cycles so that each round is a change
    cycles=$((19 + i % 2))
    sed "s/^  cycles: 30 .*/  cycles: $cycles/" "$work/xytheta-thesis.yaml" > config/campaigns/xytheta-thesis.yaml
    [ -n "$jobs" ] || jobs=$("$snakemake" -n --quiet rules --cores "$cores" 2>&1 | awk '/^[a-z_]+ +[0-9]+$/ && !seen[$1]++ {printf "%s=%s ", $1, $2}')
    change+=("$(t "$snakemake" --cores "$cores")")
done
echo "validation-only change of xytheta-thesis would run: $jobs"
echo "rerun after it: $(printf '%s\n' "${change[@]}" | best) s"
echo "calflow --help: $(for i in 1 2 3 4 5; do t "$calflow" --help; done | best) s"
echo "snakemake --report report.zip: $(t "$snakemake" --report "$work/report.zip") s"
echo "load average at the end: $(load)"
