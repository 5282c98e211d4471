"""The SLURM pre-flight (calflow.cluster): sinfo's partition lines and sacct's and scontrol's
answers, recorded from real clusters, give one sentence naming what can run no job or cannot
be read, and what to change; the cluster itself is exercised by ``make cluster-test``
(tests/cluster), not here."""

import asyncio
import getpass
import signal
import time
from types import SimpleNamespace

import pytest

from calflow.cluster import (
    PLUGIN_MAX_LOOK_GAP_S,
    check_partitions,
    choose_status_command,
    end_promptly_on_sigterm,
    parse_min_job_age,
    parse_sinfo,
    partition_problem,
    sacct_problem,
    status_command_plan,
)
from calflow.errors import ConfigError

# `sinfo -a -h -o "%P|%a|%T"` of a site: one line per partition and node state
SITE = "normal*|up|mixed\nnormal*|up|drained\ngpu|up|idle\nlong|down|idle\nbig|up|down*\nbig|up|idle*\n"
# recorded on the test cluster (SLURM 22.05, tests/cluster) with power saving configured:
# `scontrol update nodename=... state=power_down`, then a job submitted, then the node set
# down, drained, the partition set inactive and drain (the node still powering up)
POWER_SAVE = {
    "pending power down": "normal*|up|idle!\n",
    "powering down": "normal*|up|idle%\n",
    "powered down": "normal*|up|idle~\n",
    "powering up for a job": "normal*|up|mixed#\n",
    "powering up, idle": "normal*|up|idle#\n",
}
DOWN_WHILE_POWERING = {
    "down": "normal*|up|down#\n",
    "drained": "normal*|up|drained#\n",
}
# `sacct -X --parsable2 --clusters all ...` where AccountingStorageType=accounting_storage/none
SACCT_NO_ACCOUNTING = (1, "Slurm accounting storage is disabled\n")
# where slurmdbd is configured but not running
SACCT_NO_DBD = (
    1,
    "sacct: error: _open_persist_conn: failed to open persistent connection to host:localhost:6819: "
    "Connection refused\nsacct: error: Sending PersistInit msg: Connection refused\n"
    "sacct: error: Problem talking to the database: Connection refused\n",
)
# `scontrol show config`, the lines around MinJobAge, from the test cluster
SCONTROL = "MaxTasksPerNode         = 512\nMCSPlugin               = mcs/none\nMinJobAge               = 300 sec\nMpiDefault              = none\n"


def test_parse_marks_the_default_and_gathers_node_states():
    partitions, default = parse_sinfo(SITE)
    assert default == "normal"
    assert partitions["normal"] == ("up", ["mixed", "drained"])
    assert set(partitions) == {"normal", "gpu", "long", "big"}


@pytest.mark.parametrize("partition", ["normal", "gpu", None])
def test_a_partition_with_a_node_that_takes_jobs_passes(partition):
    assert partition_problem(partition, SITE) is None


@pytest.mark.parametrize("case", sorted(POWER_SAVE))
def test_nodes_slurm_powers_up_on_demand_can_run_a_job(case):
    assert partition_problem("normal", POWER_SAVE[case]) is None
    assert partition_problem(None, POWER_SAVE[case]) is None


@pytest.mark.parametrize("case", sorted(DOWN_WHILE_POWERING))
def test_a_node_down_or_drained_is_no_node_even_while_powering_up(case):
    msg = partition_problem("normal", DOWN_WHILE_POWERING[case])
    assert f"has no node that can run a job (node states: {case}#; sinfo -R says why)" in msg


@pytest.mark.parametrize("state", ["idle$", "mixed@", "allocated^", "planned-", "reserved", "maint"])
def test_nodes_waiting_for_a_reboot_or_a_reservation_can_run_a_job_later(state):
    assert partition_problem("p", f"p|up|{state}\n") is None


@pytest.mark.parametrize("state", ["fail", "failing", "draining", "future", "unknown", "unknown*", "inval"])
def test_nodes_that_take_no_job_without_an_administrator(state):
    assert "has no node that can run a job" in partition_problem("p", f"p|up|{state}\np|up|down~\n")


def test_a_missing_partition_is_named_with_the_ones_there_are():
    msg = partition_problem("nomral", SITE)
    assert "'nomral' does not exist" in msg and "big, gpu, long, normal" in msg and "\n" not in msg


def test_a_partition_set_down_starts_nothing():
    assert (
        partition_problem("long", SITE)
        == "SLURM partition 'long' is down: it starts no job (sinfo -R says why)"
    )


@pytest.mark.parametrize("avail", ["inactive", "drain"])
def test_a_partition_inactive_or_draining_starts_nothing(avail):
    assert f"'normal' is {avail}" in partition_problem("normal", f"normal*|{avail}|drained#\n")


def test_nodes_down_or_not_responding_leave_no_node():
    msg = partition_problem("big", SITE)
    assert (
        msg
        == "SLURM partition 'big' has no node that can run a job (node states: down*, idle*; sinfo -R says why)"
    )


def test_no_partition_and_no_default():
    assert "no default partition" in partition_problem(None, "gpu|up|idle\n")


@pytest.mark.parametrize("partitions", ["gpu,big", "big,gpu", "long,normal", "gpu,", "normal,long,big"])
def test_a_list_passes_when_one_of_its_partitions_can_run_the_job(partitions):
    assert partition_problem(partitions, SITE) is None


def test_a_list_naming_a_partition_that_does_not_exist_is_refused_as_sbatch_does():
    # sbatch -p normal,nosuch: "invalid partition specified: nosuch" (tests/cluster, SLURM 22.05)
    msg = partition_problem("gpu,nosuch", SITE)
    assert msg.startswith("SLURM partition 'nosuch' (in the list 'gpu,nosuch') does not exist")
    # sbatch -p "normal, normal": "invalid partition specified:  normal"; "normal," passes
    msg = partition_problem("normal, gpu", SITE)
    assert "' gpu' (in the list 'normal, gpu', which takes no spaces) does not" in msg


def test_a_list_none_of_which_can_run_a_job_names_each():
    msg = partition_problem("long,big", SITE)
    assert msg.startswith("no SLURM partition of 'long,big' can run a job: 'long' is down")
    assert msg.endswith("'big' has no node that can run a job (node states: down*, idle*; sinfo -R says why)")
    assert "\n" not in msg


def test_check_raises_one_line_for_the_first_bad_partition_and_ignores_repeats():
    with pytest.raises(ConfigError, match="'big' has no node") as err:
        check_partitions(["gpu", "big", "gpu", "", None], sinfo_text=SITE)
    assert "\n" not in str(err.value)
    check_partitions(["gpu", None, "", "big,gpu"], sinfo_text=SITE)  # the default partition is up
    check_partitions([], sinfo_text="")  # nothing to submit, nothing asked


def test_sacct_problem_reads_the_exit_status_and_error():
    assert sacct_problem(0, "") is None
    assert sacct_problem(*SACCT_NO_ACCOUNTING) == "sacct: Slurm accounting storage is disabled"
    assert "Problem talking to the database" in sacct_problem(*SACCT_NO_DBD)
    assert "\n" not in sacct_problem(*SACCT_NO_DBD)
    assert sacct_problem(None) == "'sacct' is not on PATH"
    assert sacct_problem(2, "") == "sacct: exit status 2"


@pytest.mark.parametrize(
    ("line", "seconds"),
    [("MinJobAge               = 300 sec", 300), ("MinJobAge = 2", 2), ("MinJobAge = 1h", None)],
)
def test_min_job_age(line, seconds):
    assert parse_min_job_age(f"AuthType = auth/munge\n{line}\n") == seconds


def test_min_job_age_recorded():
    assert parse_min_job_age(SCONTROL) == 300
    assert parse_min_job_age("MinJobAgeX = 5\n") is None


def test_with_accounting_nothing_changes():
    assert status_command_plan("sacct", None, 300, 40) == ("sacct", None)
    assert status_command_plan("sacct", None, None, 40) == ("sacct", None)


def test_without_accounting_squeue_reads_the_states():
    trouble = sacct_problem(*SACCT_NO_ACCOUNTING)
    command, note = status_command_plan("sacct", trouble, parse_min_job_age(SCONTROL), 40)
    assert command == "squeue"
    assert "Slurm accounting storage is disabled" in note and "300 s (MinJobAge)" in note
    assert status_command_plan("squeue", trouble, 300, 40) == ("squeue", None)  # asked for already
    assert status_command_plan("squeue", sacct_problem(None), 300, 2)[0] == "squeue"


def test_without_accounting_a_short_min_job_age_is_refused_in_one_line():
    trouble = sacct_problem(*SACCT_NO_ACCOUNTING)
    with pytest.raises(ConfigError) as err:
        status_command_plan("sacct", trouble, 60, 40)
    msg = str(err.value)
    assert "only 60 s (MinJobAge)" in msg and f"MinJobAge >= {PLUGIN_MAX_LOOK_GAP_S}" in msg
    assert "\n" not in msg
    with pytest.raises(ConfigError, match="MinJobAge could not be read"):
        status_command_plan("sacct", trouble, None, 40)


def test_without_accounting_a_late_first_look_names_the_flag():
    # the plugin goes back to sacct when MinJobAge < 3 x the first look: 300 < 3 x 120
    trouble = sacct_problem(*SACCT_NO_ACCOUNTING)
    with pytest.raises(ConfigError) as err:
        status_command_plan("squeue", trouble, 300, 120)
    assert "pass --slurm-init-seconds-before-status-checks 100 (or less; now 120)" in str(err.value)
    assert status_command_plan("sacct", trouble, 300, 100)[0] == "squeue"


def test_squeue_asked_for_where_it_would_lose_jobs_goes_back_to_sacct():
    command, note = status_command_plan("squeue", None, 200, 40)
    assert command == "sacct" and "200 s (MinJobAge)" in note


class _Executor:
    """What end_promptly_on_sigterm uses of Snakemake's remote executor."""

    run_uuid = "3f1c0d2e-run"

    def __init__(self, gap):
        self.wait, self.next_seconds_between_status_checks = True, gap

    async def sleep(self):
        await asyncio.sleep(self.next_seconds_between_status_checks)


def test_sigterm_cancels_the_run_interrupts_and_the_wait_ends_when_the_executor_stops(tmp_path, monkeypatch):
    calls = tmp_path / "scancel.args"
    _fake_commands(tmp_path, monkeypatch, scancel=f'echo "$*" >> {calls}')
    before = signal.getsignal(signal.SIGTERM)
    executor = _Executor(gap=180)
    try:
        end_promptly_on_sigterm(executor)
        with pytest.raises(KeyboardInterrupt):
            signal.raise_signal(signal.SIGTERM)
        assert signal.getsignal(signal.SIGTERM) == signal.SIG_IGN  # a repeat waits for the clean-up
        # every job named after the run, those the plugin lost track of too
        assert calls.read_text().split() == ["--name=3f1c0d2e-run", f"--user={getpass.getuser()}"]

        async def stop_soon():
            await asyncio.sleep(0.2)
            executor.wait = False

        async def both():
            start = time.monotonic()
            await asyncio.gather(executor.sleep(), stop_soon())
            return time.monotonic() - start

        assert asyncio.run(both()) < 2.0  # not the 180 s asked for
        executor.wait, executor.next_seconds_between_status_checks = True, 0.05
        asyncio.run(executor.sleep())  # a short gap is slept in full and ends
    finally:
        signal.signal(signal.SIGTERM, before)


def _fake_commands(tmp_path, monkeypatch, **scripts):
    """Executables named after the keys on PATH, each a shell script body."""
    for name, body in scripts.items():
        exe = tmp_path / name
        exe.write_text(f"#!/bin/sh\n{body}\n")
        exe.chmod(0o755)
    monkeypatch.setenv("PATH", str(tmp_path))


def test_the_commands_are_asked_as_the_plugin_asks_them(tmp_path, monkeypatch):
    _fake_commands(
        tmp_path,
        monkeypatch,
        sacct='case "$*" in *"-X --parsable2 --clusters all"*"--name calflow-preflight"*) ;;'
        ' *) echo "unexpected: $*" >&2; exit 9;; esac\n'
        'echo "Slurm accounting storage is disabled" >&2; exit 1',
        scontrol=f'[ "$*" = "show config" ] && printf "{SCONTROL}"',
        sinfo='[ "$*" = "-a -h -o %P|%a|%T" ] && printf "normal*|up|idle~\\nhidden|up|down\\n"',
    )
    settings = SimpleNamespace(status_command="sacct", init_seconds_before_status_checks=40)
    note = choose_status_command(settings)
    assert settings.status_command == "squeue" and "accounting storage is disabled" in note
    check_partitions(["normal", None])
    with pytest.raises(ConfigError, match="'hidden' has no node"):
        check_partitions(["hidden"])


def test_sacct_missing_and_min_job_age_unreadable_is_one_line(tmp_path, monkeypatch):
    _fake_commands(tmp_path, monkeypatch, scontrol="echo 'slurm_load_ctl_conf error' >&2; exit 1")
    settings = SimpleNamespace(status_command="squeue", init_seconds_before_status_checks=40)
    with pytest.raises(ConfigError, match=r"'sacct' is not on PATH, and squeue's MinJobAge could not"):
        choose_status_command(settings)
