#!/usr/bin/env bash
# Two trees back to back: the previous main and this one, the same figures as
# bench_workflow.sh (cold run, no-op reruns, a validation-only change of xytheta-thesis),
# once each, in the same session, then every result and report compared byte for byte.
#   bash benchmarks/bench_workflow_pair.sh OLD_TREE NEW_TREE [CORES]
#   CAMPAIGNS='["xytheta-thesis","nano1d-thesis","nano2d-thesis"]' bash benchmarks/bench_workflow_pair.sh OLD NEW
#       only these campaigns (each tree's config otherwise; the changed one stays xytheta-thesis)
#   bash benchmarks/bench_workflow_pair.sh --smoke TREE   # CI: the tree against itself, on a
#       shortened nano2d-thesis alone; every result and report must be the same bytes
# Each tree is a checkout with its own .venv (`make .venv/.calflow-installed`); run it on a
# quiet machine: the ratios are the figures (machines here differ ~2x in speed).
set -uo pipefail
smoke=""
if [ "${1:-}" = "--smoke" ]; then smoke=1; shift; set -- "$1" "$1" "${2:-2}"; fi
old="$(cd "$1" && pwd)"; new="$(cd "$2" && pwd)"; cores="${3:-2}"
campaign=xytheta-thesis; change_line='^  cycles: 30 .*'; sm_args=(); noops=3; changes=2
[ -z "${CAMPAIGNS:-}" ] || sm_args=(--config "campaigns=$CAMPAIGNS")
if [ -n "$smoke" ]; then  # each step once
    campaign=nano2d-thesis; change_line='^  cycles: 4$'; sm_args=(--config 'campaigns=["nano2d-thesis"]')
    noops=1; changes=1
fi
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
export SOURCE_DATE_EPOCH=1767225600
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores; --cores $cores"
timed() {  # timed LABEL CMD...: wall and CPU (user + sys, children included)
    local label=$1; shift
    /usr/bin/time -o "$work/t.txt" -f '%e %U %S' "$@" > "$work/last.log" 2>&1 || { echo "$label: failed"; failed=1; }
    read -r w u s < "$work/t.txt"
    echo "$label wall=$w cpu=$(python3 -c "print(round($u + $s, 2))") load=$(cut -d' ' -f1 /proc/loadavg)"
}
for pair in "old:$old" "new:$new"; do
    name=${pair%%:*}; tree=${pair#*:}; p="$work/$name/p"; mkdir -p "$p"
    cp -r "$tree/Snakefile" "$tree/workflow" "$tree/config" "$p/"
    if [ -n "$smoke" ]; then  # 2 training cycles, 2 validation tests of 4 cycles
        sed -i -e 's/cycles: 12,/cycles: 2,/' -e 's/^  tests: 16 .*/  tests: 2/' -e 's/^  cycles: 20$/  cycles: 4/' \
            "$p/config/campaigns/nano2d-thesis.yaml"
    fi
    sm="$tree/.venv/bin/snakemake"
    # each tree its own empty cache (calflow.cache): a cold run keeps nothing from earlier runs
    export CALFLOW_CACHE_DIR="$work/$name/cache"
    cd "$p"
    timed "$name cold" "$sm" --cores "$cores" "${sm_args[@]}"
    for i in $(seq "$noops"); do timed "$name no-op $i" "$sm" --cores "$cores" "${sm_args[@]}"; done
    cp "config/campaigns/$campaign.yaml" "$work/$name/orig.yaml"
    for i in $(seq "$changes"); do  # alternate the cycles so that each round is a change
        cycles=$((19 + i % 2)); [ -z "$smoke" ] || cycles=$((4 + i % 2))
        sed "s/$change_line/  cycles: $cycles/" "$work/$name/orig.yaml" > "config/campaigns/$campaign.yaml"
        timed "$name validation-only $i" "$sm" --cores "$cores" "${sm_args[@]}"
    done
done
a="$work/old/p"; b="$work/new/p"
same=0; differ=0
# the index shows each run's measured footprint (peak memory, CPU): it differs between runs
for f in $(cd "$a" && find results reports -type f | grep -v -e /logs/ -e /benchmarks/ -e '^reports/index.html$' | sort); do
    if cmp -s "$a/$f" "$b/$f"; then same=$((same + 1)); else differ=$((differ + 1)); echo "differs: $f"; fi
done
echo "results and reports: $same identical, $differ differ (logs, benchmark files and the index aside)"
if [ -n "$smoke" ]; then  # one tree against itself: the same bytes, and a run that did something
    [ "$same" -gt 0 ] && [ "$differ" -eq 0 ] && [ -z "${failed:-}" ] || exit 1
fi
