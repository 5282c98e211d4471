#!/usr/bin/env bash
# Two trees back to back: the previous main and this one, the same figures as
# bench_workflow.sh (cold run, no-op reruns, a validation-only change of xytheta-thesis),
# once each, in the same session, then every result and report compared byte for byte.
#   bash benchmarks/bench_workflow_pair.sh OLD_TREE NEW_TREE [CORES]
# Each tree is a checkout with its own .venv (`make .venv/.calflow-installed`); run it on a
# quiet machine: the ratios are the figures (machines here differ ~2x in speed).
set -uo pipefail
old="$(cd "$1" && pwd)"; new="$(cd "$2" && pwd)"; cores="${3:-2}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
export SOURCE_DATE_EPOCH=1767225600
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores; --cores $cores"
timed() {  # timed LABEL CMD...: wall and CPU (user + sys, children included)
    local label=$1; shift
    /usr/bin/time -o "$work/t.txt" -f '%e %U %S' "$@" > "$work/last.log" 2>&1 || echo "$label: failed"
    read -r w u s < "$work/t.txt"
    echo "$label wall=$w cpu=$(python3 -c "print(round($u + $s, 2))") load=$(cut -d' ' -f1 /proc/loadavg)"
}
for pair in "old:$old" "new:$new"; do
    name=${pair%%:*}; tree=${pair#*:}; p="$work/$name/p"; mkdir -p "$p"
    cp -r "$tree/Snakefile" "$tree/workflow" "$tree/config" "$p/"
    sm="$tree/.venv/bin/snakemake"
    cd "$p"
    timed "$name cold" "$sm" --cores "$cores"
    for i in 1 2 3; do timed "$name no-op $i" "$sm" --cores "$cores"; done
    cp config/campaigns/xytheta-thesis.yaml "$work/$name/orig.yaml"
    for i in 1 2; do  # alternate the cycles so that each round is a change
        sed "s/^  cycles: 30 .*/  cycles: $((19 + i % 2))/" "$work/$name/orig.yaml" > config/campaigns/xytheta-thesis.yaml
        timed "$name validation-only $i" "$sm" --cores "$cores"
    done
done
a="$work/old/p"; b="$work/new/p"
same=0; differ=0
for f in $(cd "$a" && find results reports -type f | grep -v -e /logs/ -e /benchmarks/ | sort); do
    if cmp -s "$a/$f" "$b/$f"; then same=$((same + 1)); else differ=$((differ + 1)); echo "differs: $f"; fi
done
echo "results and reports: $same identical, $differ differ (logs and benchmark files aside)"
