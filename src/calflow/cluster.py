"""Pre-flight check of the SLURM partitions a workflow run is about to submit to.

A job sent to a partition that does not exist fails at submission with sbatch's two-line
message inside Snakemake's error block; a job sent to a partition whose nodes are all down
is accepted and then waits in the queue for ever, with no message at all. Both are checked
once, before the first submission, and reported as one line (docs/cluster.md).

The check reads ``sinfo``'s per-node-state lines (partition, availability, node state;
SLURM's ``sinfo -o "%P|%a|%T"``); node-state names and their flag suffixes (``*`` not
responding, ``~`` powered off, ``#`` powering up, ``!`` powering down, ``%`` powering
down, ``$`` maintenance, ``@`` pending reboot, ``^`` rebooting, ``-`` planned) are those of
SLURM's sinfo manual, "NODE STATE CODES".
"""

from __future__ import annotations

import subprocess
from collections.abc import Iterable

from calflow.errors import ConfigError

#: node states in which a node takes new jobs (sinfo's long names, flags stripped)
RUNNABLE_STATES = frozenset({"idle", "mixed", "allocated", "completing", "planned"})
#: flag suffixes of a node state that mean it takes no job now, though its state is runnable
UNAVAILABLE_FLAGS = frozenset("*~#!%$@^")
SINFO_FORMAT = "%P|%a|%T"


def parse_sinfo(text: str) -> tuple[dict[str, tuple[str, list[str]]], str | None]:
    """Partitions of ``sinfo -h -o "%P|%a|%T"`` output: ``{name: (availability, node
    states)}`` and the default partition's name (sinfo marks it with ``*``), or None."""
    partitions: dict[str, tuple[str, list[str]]] = {}
    default = None
    for line in text.splitlines():
        if not line.strip():
            continue
        name, avail, state = (field.strip() for field in line.split("|", 2))
        if name.endswith("*"):
            name = name[:-1]
            default = name
        avail_states = partitions.setdefault(name, (avail, []))
        avail_states[1].append(state)
    return partitions, default


def _runnable(state: str) -> bool:
    flags = set(state) & UNAVAILABLE_FLAGS
    return state.rstrip("".join(UNAVAILABLE_FLAGS)).lower() in RUNNABLE_STATES and not flags


def partition_problem(partition: str | None, sinfo_text: str) -> str | None:
    """Why ``partition`` (None: the cluster's default partition) can run no job now, as one
    sentence, or None when at least one of its nodes takes jobs."""
    partitions, default = parse_sinfo(sinfo_text)
    if partition is None:
        if default is None:
            return "no SLURM partition was given and the cluster has no default partition"
        partition = default
    if partition not in partitions:
        known = ", ".join(sorted(partitions)) or "none"
        return (
            f"SLURM partition {partition!r} does not exist on this cluster (its partitions: "
            f"{known}); set slurm_partition in workflow/profiles/slurm/config.yaml"
        )
    avail, states = partitions[partition]
    if avail.lower() != "up":
        return f"SLURM partition {partition!r} is {avail}: it starts no job (sinfo -R says why)"
    if not any(_runnable(s) for s in states):
        return (
            f"SLURM partition {partition!r} has no node that can run a job "
            f"(node states: {', '.join(sorted(set(states)))}; sinfo -R says why)"
        )
    return None


def run_sinfo() -> str:
    """``sinfo``'s partition and node-state lines, from the cluster SLURM's configuration names."""
    try:
        proc = subprocess.run(
            ["sinfo", "-h", "-o", SINFO_FORMAT],
            capture_output=True,
            text=True,
            timeout=60,
        )
    except FileNotFoundError:
        raise ConfigError(
            "the SLURM executor was chosen but 'sinfo' is not on PATH: "
            "run Snakemake on a machine of the cluster (a login node)"
        ) from None
    except subprocess.TimeoutExpired:
        raise ConfigError("'sinfo' did not answer within 60 s: is slurmctld reachable?") from None
    if proc.returncode != 0:
        reason = " ".join(proc.stderr.split()) or f"exit status {proc.returncode}"
        raise ConfigError(f"'sinfo' failed: {reason}")
    return proc.stdout


def check_partitions(partitions: Iterable[str | None], sinfo_text: str | None = None) -> None:
    """Raise :class:`ConfigError` with one line naming the first partition of ``partitions``
    that cannot run a job now (see :func:`partition_problem`); empty names mean the default."""
    wanted = sorted({p or None for p in partitions}, key=lambda p: (p is not None, p or ""))
    if not wanted:
        return
    text = run_sinfo() if sinfo_text is None else sinfo_text
    for partition in wanted:
        problem = partition_problem(partition, text)
        if problem:
            raise ConfigError(problem)
