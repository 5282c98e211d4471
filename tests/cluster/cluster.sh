#!/usr/bin/env bash
# A one-node SLURM cluster without systemd: munged, slurmctld and slurmd started here as
# root, all state under $CALFLOW_SLURM_STATE (default /tmp/calflow-slurm).
#   tests/cluster/cluster.sh install   Debian packages (slurmctld, slurmd, slurm-client, munge)
#   tests/cluster/cluster.sh start     write slurm.conf (this node's CPUs and memory), start
#   tests/cluster/cluster.sh stop      stop the three daemons this script started
# Clients find the cluster through /etc/slurm/slurm.conf, a link to the generated file made
# at start (only where no slurm.conf is there) and removed at stop: the executor plugin's
# job step drops every SLURM_* variable, SLURM_CONF too, before its nested srun.
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
STATE="${CALFLOW_SLURM_STATE:-/tmp/calflow-slurm}"
PARTITION="${CALFLOW_SLURM_PARTITION:-normal}"
CTLD_PORT="${CALFLOW_SLURMCTLD_PORT:-6817}"
SLURMD_PORT="${CALFLOW_SLURMD_PORT:-6818}"
CONF="$STATE/slurm.conf"
SYSTEM_CONF=/etc/slurm/slurm.conf
# CALFLOW_NICE: the daemons, and so the jobs, at that niceness (a shared machine)
NICE="nice -n ${CALFLOW_NICE:-0}"

log() { echo "cluster.sh: $*" >&2; }

install() {
    if command -v slurmctld >/dev/null && command -v slurmd >/dev/null \
        && command -v sbatch >/dev/null && command -v munged >/dev/null; then
        return 0
    fi
    log "installing slurmctld slurmd slurm-client munge"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    # policy-rc.d and no systemd: the packages' services are not started, this script does it
    apt-get install -y -qq --no-install-recommends slurmctld slurmd slurm-client munge >/dev/null
}

pid_alive() { [[ -f "$1" ]] && kill -0 "$(cat "$1")" 2>/dev/null; }

start_slurmd() {
    $NICE slurmd -f "$CONF"
    wait_for "slurmd" pid_alive "$STATE/slurmd.pid"
}

wait_for() {  # wait_for WHAT COMMAND ARGS...: up to 30 s
    local what="$1"; shift
    for _ in $(seq 60); do
        if "$@" >/dev/null 2>&1; then return 0; fi
        sleep 0.5
    done
    log "error: $what did not come up; its log: $STATE/log/"
    tail -n 20 "$STATE"/log/*.log >&2 || true
    return 1
}

node_ready() {
    local state
    state="$(sinfo -h -p "$PARTITION" -o %T 2>/dev/null | head -n1)"
    [[ "$state" == idle* || "$state" == mixed* || "$state" == allocated* ]]
}

start() {
    install
    stop_daemons
    rm -rf "$STATE"
    mkdir -p "$STATE"/{munge,ctld,slurmd,log}
    chmod 700 "$STATE/munge"
    local host cpus mem
    host="$(hostname -s)"
    cpus="$(nproc)"
    # slurmd -C reports the memory slurmd will see; the node may not declare more
    mem="$(slurmd -C | sed -n 's/.*RealMemory=\([0-9]*\).*/\1/p')"
    sed -e "s|@HOST@|$host|g" -e "s|@CPUS@|$cpus|g" -e "s|@MEM_MB@|$mem|g" \
        -e "s|@STATE@|$STATE|g" -e "s|@PARTITION@|$PARTITION|g" \
        -e "s|@CTLD_PORT@|$CTLD_PORT|g" -e "s|@SLURMD_PORT@|$SLURMD_PORT|g" \
        "$HERE/slurm.conf.in" >"$CONF"
    # a key of our own: nothing of the machine's munge is used or changed
    if [[ -e "$SYSTEM_CONF" && "$(readlink "$SYSTEM_CONF" || true)" != "$CONF" ]]; then
        log "error: $SYSTEM_CONF exists and is not this test cluster's; not starting"
        return 1
    fi
    mkdir -p "$(dirname "$SYSTEM_CONF")"
    ln -sfn "$CONF" "$SYSTEM_CONF"
    dd if=/dev/urandom of="$STATE/munge/munge.key" bs=1024 count=1 status=none
    chmod 400 "$STATE/munge/munge.key"
    $NICE munged --force --key-file="$STATE/munge/munge.key" --socket="$STATE/munge/munge.socket" \
        --pid-file="$STATE/munge/munged.pid" --log-file="$STATE/log/munged.log" \
        --seed-file="$STATE/munge/munged.seed"
    wait_for "munged" test -S "$STATE/munge/munge.socket"
    $NICE slurmctld -f "$CONF"
    wait_for "slurmctld" scontrol ping
    start_slurmd
    wait_for "node $host in partition $PARTITION" node_ready
    log "up: node $host, $cpus CPUs, $mem MB, partition $PARTITION, $SYSTEM_CONF -> $CONF"
}

stop_one() {  # stop_one PIDFILE NAME
    local pidfile="$1" name="$2" pid
    [[ -f "$pidfile" ]] || return 0
    pid="$(cat "$pidfile")"
    if kill -0 "$pid" 2>/dev/null; then
        kill "$pid" 2>/dev/null || true
        for _ in $(seq 40); do kill -0 "$pid" 2>/dev/null || break; sleep 0.25; done
        kill -9 "$pid" 2>/dev/null || true
        log "stopped $name ($pid)"
    fi
    rm -f "$pidfile"
}

stop_daemons() {
    [[ -d "$STATE" ]] || return 0
    if [[ -f "$STATE/slurmctld.pid" ]] && kill -0 "$(cat "$STATE/slurmctld.pid")" 2>/dev/null; then
        # jobs still queued or running belong to this cluster only
        scancel --full --quiet --user=root 2>/dev/null || true
    fi
    stop_one "$STATE/slurmd.pid" slurmd
    stop_one "$STATE/slurmctld.pid" slurmctld
    stop_one "$STATE/munge/munged.pid" munged
    if [[ "$(readlink "$SYSTEM_CONF" || true)" == "$CONF" ]]; then rm -f "$SYSTEM_CONF"; fi
}

case "${1:-}" in
    install) install ;;
    start) start ;;
    stop) stop_daemons ;;
    restart-slurmd) stop_one "$STATE/slurmd.pid" slurmd; start_slurmd ;;
    kill-slurmd) kill -9 "$(cat "$STATE/slurmd.pid")"; rm -f "$STATE/slurmd.pid"; log "killed slurmd" ;;
    start-slurmd) start_slurmd ;;
    *) echo "usage: $0 install|start|stop|kill-slurmd|start-slurmd" >&2; exit 2 ;;
esac
