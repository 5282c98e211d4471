"""Pre-flight of a SLURM run: the partitions its jobs name, how job states will be read, and
an interruption that ends the run (docs/cluster.md).

Partitions. A job sent to a partition that does not exist fails at submission with sbatch's
two-line message inside Snakemake's error block; a job sent to a partition whose nodes are
all down is accepted and then waits in the queue for ever, with no message at all. Both are
checked once, before the first submission, and reported as one line. What sbatch accepts
passes: a comma-separated list of partitions (every name must exist, as sbatch requires;
one partition that can run the job is enough), and nodes that are powered down, powering up
or down, rebooting or in a maintenance reservation, which SLURM resumes or frees by itself.
The check reads ``sinfo``'s per-node-state lines of every partition, hidden ones too
(SLURM's ``sinfo -a -h -o "%P|%a|%T"``); node-state names and their flag suffixes (``*``
not responding, ``~`` powered off, ``#`` powering up, ``!`` powering down soon, ``%``
powering down, ``$`` maintenance, ``@`` pending reboot, ``^`` rebooting, ``-`` planned) are
those of SLURM's sinfo manual, "NODE STATE CODES".

Job states. The executor plugin reads them with ``sacct`` when that command is on PATH; on a
cluster without an accounting database ``sacct`` fails at once ("Slurm accounting storage
is disabled"), the plugin then stops tracking the jobs it asked about, and Snakemake waits
for ever. :func:`status_command_plan` decides, before the first submission, whether
``squeue`` can serve instead (it keeps a finished job ``MinJobAge`` seconds, and the plugin
may look only every 180 s) and switches to it, or says in one line what to change.

Interruption. Snakemake takes SIGTERM as "finish the running jobs, then stop"; a SLURM job
may run for hours, and a job whose state the plugin lost never finishes. In a SLURM run
calflow makes SIGTERM act as Ctrl-C (the run's SLURM jobs are cancelled, Snakemake stops),
and makes the plugin's wait between two looks end within a second once it is told to stop.
"""

from __future__ import annotations

import asyncio
import getpass
import shutil
import signal
import subprocess
import time
from collections.abc import Iterable
from datetime import datetime, timedelta

from calflow.errors import ConfigError

#: node states in which a node takes new jobs, now or once SLURM has resumed it or a
#: reservation has ended (sinfo's long names, flag suffixes stripped)
RUNNABLE_STATES = frozenset({"idle", "mixed", "allocated", "completing", "planned", "reserved", "maint"})
#: all flag suffixes of a node state
STATE_FLAGS = "*~#!%$@^-"
#: the flag that keeps a node of a runnable state from taking jobs: not responding
UNAVAILABLE_FLAGS = frozenset("*")
SINFO_FORMAT = "%P|%a|%T"
#: the longest the executor plugin (2.8.0) waits between two looks at its jobs, plus the
#: longest a look may take before it gives up (its query timeout): a finished job must stay
#: in squeue at least this long to be seen
PLUGIN_MAX_LOOK_GAP_S = 180 + 60
PROFILE = "workflow/profiles/slurm/config.yaml"


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
    return state.rstrip(STATE_FLAGS).lower() in RUNNABLE_STATES and not flags


def _why_not(name: str, avail: str, states: list[str]) -> str | None:
    """Why the partition ``name`` starts no job, or None when it can."""
    if avail.lower() != "up":
        return f"{name!r} is {avail}: it starts no job"
    if not any(_runnable(s) for s in states):
        return f"{name!r} has no node that can run a job (node states: {', '.join(sorted(set(states)))})"
    return None


def partition_problem(partition: str | None, sinfo_text: str) -> str | None:
    """Why ``partition`` (None: the cluster's default partition; ``"a,b"``: a list, as
    sbatch takes it) can run no job, as one sentence, or None when it can."""
    partitions, default = parse_sinfo(sinfo_text)
    if partition is None:
        if default is None:
            return "no SLURM partition was given and the cluster has no default partition"
        partition = default
    names = [n for n in partition.split(",") if n]  # sbatch skips empty list items
    known = ", ".join(sorted(partitions)) or "none"
    for name in names:
        if name not in partitions:
            spaced = ", which takes no spaces" if name != name.strip() else ""
            within = f" (in the list {partition!r}{spaced})" if len(names) > 1 else ""
            return (
                f"SLURM partition {name!r}{within} does not exist on this cluster (its "
                f"partitions: {known}); set slurm_partition in {PROFILE}"
            )
    reasons = [_why_not(n, *partitions[n]) for n in names]
    if not names or not all(reasons):
        return None
    if len(names) == 1:
        return _hint(f"SLURM partition {reasons[0]}")
    return _hint(f"no SLURM partition of {partition!r} can run a job: {'; '.join(reasons)}")


def _hint(sentence: str) -> str:
    """``sentence`` pointing to ``sinfo -R``, inside its closing parenthesis if it has one."""
    if sentence.endswith(")"):
        return f"{sentence[:-1]}; sinfo -R says why)"
    return f"{sentence} (sinfo -R says why)"


def _run(cmd: list[str], what: str, timeout: float = 60) -> subprocess.CompletedProcess:
    try:
        return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except FileNotFoundError:
        raise ConfigError(
            f"the SLURM executor was chosen but {cmd[0]!r} is not on PATH: "
            "run Snakemake on a machine of the cluster (a login node)"
        ) from None
    except subprocess.TimeoutExpired:
        raise ConfigError(f"{what} did not answer within {timeout:.0f} s: is slurmctld reachable?") from None


def _squash(text: str) -> str:
    return " ".join(text.split())


def run_sinfo() -> str:
    """``sinfo``'s partition and node-state lines, hidden partitions included."""
    proc = _run(["sinfo", "-a", "-h", "-o", SINFO_FORMAT], "'sinfo'")
    if proc.returncode != 0:
        raise ConfigError(f"'sinfo' failed: {_squash(proc.stderr) or f'exit status {proc.returncode}'}")
    return proc.stdout


def check_partitions(partitions: Iterable[str | None], sinfo_text: str | None = None) -> None:
    """Raise :class:`ConfigError` with one line naming the first partition (or list) of
    ``partitions`` that can run no job (see :func:`partition_problem`); empty names mean
    the default partition."""
    wanted = sorted({p or None for p in partitions}, key=lambda p: (p is not None, p or ""))
    if not wanted:
        return
    text = run_sinfo() if sinfo_text is None else sinfo_text
    for partition in wanted:
        problem = partition_problem(partition, text)
        if problem:
            raise ConfigError(problem)


def sacct_problem(returncode: int | None, stderr: str = "") -> str | None:
    """Why ``sacct`` cannot tell job states on this cluster, from the exit status and error
    output of the plugin's own query (None: ``sacct`` is not on PATH), or None when it can."""
    if returncode is None:
        return "'sacct' is not on PATH"
    if returncode == 0:
        return None
    return f"sacct: {_squash(stderr) or f'exit status {returncode}'}"


def parse_min_job_age(scontrol_config: str) -> int | None:
    """``MinJobAge`` in seconds from ``scontrol show config`` ("MinJobAge = 300 sec"), or
    None when the line is missing or unreadable."""
    for line in scontrol_config.splitlines():
        key, _, value = line.partition("=")
        if key.strip() != "MinJobAge":
            continue
        number, _, unit = value.strip().partition(" ")
        if not number.isdigit():
            return None
        scale = {"": 1, "s": 1, "sec": 1, "secs": 1, "min": 60, "h": 3600, "hours": 3600}
        return int(number) * scale[unit.strip()] if unit.strip() in scale else None
    return None


def status_command_plan(
    chosen: str, sacct_trouble: str | None, min_job_age: int | None, first_look_s: int
) -> tuple[str, str | None]:
    """The command the executor plugin should read job states with, and a note for the user
    (None: nothing changes), or :class:`ConfigError` in one line naming what to change.

    ``chosen``: the plugin's ``status_command`` setting; ``sacct_trouble``: what
    :func:`sacct_problem` said; ``min_job_age``: slurmctld's ``MinJobAge`` (s);
    ``first_look_s``: the plugin's ``init_seconds_before_status_checks``. The plugin itself
    goes back to ``sacct`` when ``MinJobAge`` < 3 × ``first_look_s`` and ``sacct`` is on PATH.
    """
    squeue_keeps_long_enough = min_job_age is not None and min_job_age >= PLUGIN_MAX_LOOK_GAP_S
    if sacct_trouble is None:
        if chosen == "squeue" and not squeue_keeps_long_enough:
            return "sacct", (
                f"squeue keeps a finished job {min_job_age} s (MinJobAge), less than the "
                f"{PLUGIN_MAX_LOOK_GAP_S} s the SLURM plugin may take between two looks: job "
                "states are read with sacct"
            )
        return chosen, None
    if min_job_age is None:
        raise ConfigError(
            f"SLURM job states cannot be read: {sacct_trouble}, and squeue's MinJobAge could "
            "not be read ('scontrol show config'); ask the cluster's administrators"
        )
    if min_job_age < PLUGIN_MAX_LOOK_GAP_S:
        raise ConfigError(
            f"SLURM job states cannot be read: {sacct_trouble}, and squeue keeps a finished job "
            f"only {min_job_age} s (MinJobAge), less than the {PLUGIN_MAX_LOOK_GAP_S} s the "
            "SLURM plugin may take between two looks; ask the administrators for accounting "
            f"(slurmdbd) or MinJobAge >= {PLUGIN_MAX_LOOK_GAP_S}"
        )
    if min_job_age < 3 * first_look_s:
        raise ConfigError(
            f"SLURM job states cannot be read: {sacct_trouble}, and squeue, which keeps a "
            f"finished job {min_job_age} s (MinJobAge), is used only when the first look comes "
            f"within a third of that: pass --slurm-init-seconds-before-status-checks "
            f"{min_job_age // 3} (or less; now {first_look_s})"
        )
    note = (
        f"no SLURM accounting here ({sacct_trouble}): job states are read with squeue, "
        f"which keeps a finished job {min_job_age} s (MinJobAge)"
    )
    return "squeue", note if chosen != "squeue" else None


def probe_sacct() -> str | None:
    """:func:`sacct_problem` of the query the plugin runs (same options, a name no job has)."""
    if shutil.which("sacct") is None:
        return sacct_problem(None)
    start = f"{datetime.now() - timedelta(days=2):%Y-%m-%dT%H:00}"
    cmd = ["sacct", "-X", "--parsable2", "--clusters", "all", "--noheader"]
    cmd += ["--format=JobIdRaw,State", "--starttime", start, "--endtime", "now"]
    try:
        proc = subprocess.run(
            [*cmd, "--name", "calflow-preflight"], capture_output=True, text=True, timeout=60
        )
    except subprocess.TimeoutExpired:
        return "sacct did not answer within 60 s"
    return sacct_problem(proc.returncode, proc.stderr)


def read_min_job_age() -> int | None:
    """slurmctld's ``MinJobAge`` (s), or None when ``scontrol`` cannot say."""
    try:
        proc = subprocess.run(["scontrol", "show", "config"], capture_output=True, text=True, timeout=60)
    except (FileNotFoundError, subprocess.TimeoutExpired):
        return None
    return parse_min_job_age(proc.stdout) if proc.returncode == 0 else None


def choose_status_command(settings) -> str | None:
    """Set ``settings.status_command`` (the SLURM plugin's executor settings) to a command
    that can read this cluster's job states; the note to show the user, or None. Raises
    :class:`ConfigError` in one line when neither can."""
    chosen = getattr(settings, "status_command", None) or "sacct"
    first_look = getattr(settings, "init_seconds_before_status_checks", None) or 40
    command, note = status_command_plan(chosen, probe_sacct(), read_min_job_age(), first_look)
    settings.status_command = command
    return note


def cancel_run(job_name: str) -> None:
    """Cancel every SLURM job of this user named ``job_name`` (the plugin names each job of
    a run after the run's id), also those whose state the plugin has lost; errors ignored:
    Snakemake's own cancel follows."""
    try:
        subprocess.run(
            ["scancel", f"--name={job_name}", f"--user={getpass.getuser()}"],
            capture_output=True,
            timeout=30,
        )
    except (FileNotFoundError, subprocess.TimeoutExpired):
        pass


def end_promptly_on_sigterm(executor=None) -> None:
    """Make SIGTERM act as Ctrl-C (Snakemake cancels the run's SLURM jobs and stops) after
    cancelling every job named after the run (``executor.run_uuid``, see :func:`cancel_run`),
    and ``executor``'s wait between two looks at its jobs (a remote executor's ``sleep``, up
    to 180 s for the SLURM plugin) end within a second once the executor is shut down, so the
    run ends within seconds. Call in the main thread, after Snakemake set its own handler."""
    run_name = getattr(executor, "run_uuid", None)

    def interrupt(signum, frame):
        signal.signal(signal.SIGTERM, signal.SIG_IGN)  # the clean-up runs once, to its end
        if run_name:
            cancel_run(run_name)
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, interrupt)
    if executor is None or not hasattr(executor, "wait") or not hasattr(executor, "sleep"):
        return

    async def sleep() -> None:
        gap = executor.next_seconds_between_status_checks
        end = time.monotonic() + gap
        while executor.wait and time.monotonic() < end:
            await asyncio.sleep(min(1.0, end - time.monotonic()))

    executor.sleep = sleep
