# Before a SLURM run submits its first job: each partition its jobs name exists and has a
# node that takes jobs, job states can be read (sacct, or squeue where accounting is off),
# and SIGTERM will end the run within seconds; or one line says what to change
# (calflow.cluster, docs/cluster.md).
import sys

from calflow.cluster import (
    check_partitions,
    choose_status_command,
    end_promptly_on_sigterm,
)
from calflow.errors import ConfigError


# The index page (a second) runs where Snakemake runs (on a cluster, the login node)
# instead of waiting in the queue as a SLURM job of its own.
localrules:
    index,


onstart:
    if (
        workflow.executor_plugin is not None
        and workflow.executor_plugin.name == "slurm"
    ):
        try:
            check_partitions(
                job.resources.get("slurm_partition")
                for job in workflow.dag.needrun_jobs()
            )
            note = choose_status_command(workflow.executor_settings)
        except ConfigError as exc:
            sys.stderr.write(f"calflow: error: {exc}\n")
            sys.exit(2)
        if note:
            sys.stderr.write(f"calflow: {note}\n")
        end_promptly_on_sigterm(getattr(workflow.scheduler, "_executor", None))
