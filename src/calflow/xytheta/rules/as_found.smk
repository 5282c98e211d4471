# The as-found run of a recalibration (docs/lifecycle.md, "As found, as left"): the
# campaign's held-out targets commanded in closed loop through the earlier calibration's
# exported bundle of the model in use, before anything is adjusted. Its metrics are the
# core's rule. It goes first: of the jobs ready to run, Snakemake starts the one of highest
# priority, so a real rig (one plan at a time, the `rig` resource) measures the stage as found
# before the campaign's open-loop runs. Not an input of those runs: they do not read it, and
# an order-only (`ancient`) input made Snakemake skip their own changed params whenever this
# run reran (snakemake/snakemake#4166) and, in the group, refuse the DAG.


rule acquire_as_found:
    input:
        manifest=as_found_export,
    output:
        run=layout.run("{campaign}", "as_found"),
        truth=layout.truth("{campaign}", "as_found"),
    log:
        layout.log("{campaign}", "acquire_as_found"),
    benchmark:
        layout.benchmark("{campaign}", "acquire_as_found")
    priority: 10
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=300,
        runtime=1,
        rig=rig_slots,
    params:
        **reads(
            "acquire",
            "as_found",
            "validation.heldout",
            "validation.dwell_s",
            "identification",
        ),
        campaign=campaign_file,
        folder=lambda w, input: os.path.join(
            os.path.dirname(input.manifest), CAMPAIGN[w.campaign]["as_found"]["model"]
        ),
    shell:
        "calflow acquire --campaign {params.campaign} --sections {params.sections:q} --plan as_found"
        " --export {params.folder} --out {output.run} --truth {output.truth} > {log} 2>&1"
