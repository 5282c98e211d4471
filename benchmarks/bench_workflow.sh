#!/usr/bin/env bash
# Workflow benchmarks: cold run of the default campaigns, a no-op rerun, and a rerun
# after a validation-only change of one campaign, in a scratch copy of the project.
#   bash benchmarks/bench_workflow.sh [CORES] [REPEATS]
#   bash benchmarks/bench_workflow.sh --smoke     # CI: the same steps on a shortened nano2d-thesis alone, once
# Each figure is the best of REPEATS (default 3) — on a shared machine the best is the
# one least disturbed by the other work, and the load average is printed beside it. The
# cold run also reports the CPU time of Snakemake and all its jobs (/usr/bin/time, user +
# sys), which other work on the machine disturbs much less than wall time.
# (the Monte-Carlo study is part of the default run; CLI start-up and snakemake --report last)
set -euo pipefail
smoke=""
if [ "${1:-}" = "--smoke" ]; then smoke=1; shift; fi
cores="${1:-2}"
repeats="${2:-3}"
campaign=xytheta-thesis; change_line='^  cycles: 30 .*'; sm_args=()
if [ -n "$smoke" ]; then  # the code path at a small size: one short campaign, each figure once
    repeats=1; campaign=nano2d-thesis; change_line='^  cycles: 4$'
    sm_args=(--config 'campaigns=["nano2d-thesis"]')
fi
root="$(cd "$(dirname "$0")/.." && pwd)"
snakemake="$root/.venv/bin/snakemake"
calflow="$root/.venv/bin/calflow"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores; --cores $cores; best of $repeats"
t() { local s; s=$(date +%s.%N); "$@" > /dev/null 2>&1; python3 -c "print(round($(date +%s.%N) - $s, 1))"; }
best() { sort -n | head -1; }
load() { cut -d' ' -f1 /proc/loadavg; }
fresh() {  # a scratch project with no results, and an empty cache (calflow.cache): a cold run keeps nothing
    rm -rf "$work/p" "$work/cache"; mkdir "$work/p"
    export CALFLOW_CACHE_DIR="$work/cache"
    cp -r "$root/Snakefile" "$root/workflow" "$root/config" "$work/p/"
    if [ -n "$smoke" ]; then  # 2 training cycles, 2 validation tests of 4 cycles
        sed -i -e 's/cycles: 12,/cycles: 2,/' -e 's/^  tests: 16 .*/  tests: 2/' -e 's/^  cycles: 20$/  cycles: 4/' \
            "$work/p/config/campaigns/nano2d-thesis.yaml"
    fi
}
cold=(); for i in $(seq "$repeats"); do
    fresh; l=$(load); cd "$work/p"
    /usr/bin/time -o "$work/time.txt" -f '%e %U %S' "$snakemake" --cores "$cores" "${sm_args[@]}" > /dev/null 2>&1
    read -r wall user sys < "$work/time.txt"; cold+=("$wall")
    echo "  cold run $i: $wall s wall, $(python3 -c "print(round($user + $sys))") s CPU (load average before: $l)"
done
echo "cold run of the default campaigns: $(printf '%s\n' "${cold[@]}" | best) s"
cd "$work/p"
test -s "reports/$campaign/certificate.pdf"  # the run finished (its outputs, not only its status)
echo "no-op rerun: $(for i in $(seq "$repeats"); do t "$snakemake" --cores "$cores" "${sm_args[@]}"; done | best) s"
cp "config/campaigns/$campaign.yaml" "$work/$campaign.yaml"
jobs=""; change=()
for i in $(seq "$repeats"); do  # alternate the cycles so that each round is a change
    cycles=$((19 + i % 2))
    [ -z "$smoke" ] || cycles=$((4 + i % 2))
    sed "s/$change_line/  cycles: $cycles/" "$work/$campaign.yaml" > "config/campaigns/$campaign.yaml"
    [ -n "$jobs" ] || jobs=$("$snakemake" -n --quiet rules --cores "$cores" "${sm_args[@]}" 2>&1 | awk '/^[a-z_]+ +[0-9]+$/ && !seen[$1]++ {printf "%s=%s ", $1, $2}')
    change+=("$(t "$snakemake" --cores "$cores" "${sm_args[@]}")")
done
[ -n "$jobs" ] || { echo "the validation-only change of $campaign ran no job"; exit 1; }
echo "validation-only change of $campaign would run: $jobs"
echo "rerun after it: $(printf '%s\n' "${change[@]}" | best) s"
echo "calflow --help: $(for i in 1 2 3 4 5; do t "$calflow" --help; done | best) s"
echo "snakemake --report report.zip: $(t "$snakemake" "${sm_args[@]}" --report "$work/report.zip") s"
echo "load average at the end: $(load)"
