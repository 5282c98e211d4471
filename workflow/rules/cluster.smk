# Before a SLURM run submits its first job: each partition its jobs name exists and has a
# node that takes jobs, or one line says which does not (calflow.cluster, docs/cluster.md).
from calflow.cluster import check_partitions


# Jobs of a second or two that gather the others' results run where Snakemake runs (on a
# cluster, the login node) instead of waiting in the queue as a SLURM job of their own.
localrules:
    index,
    mc_aggregate,
    mc_report,


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
        except ConfigError as exc:
            sys.stderr.write(f"calflow: error: {exc}\n")
            sys.exit(2)
