# The as-found run of a recalibration (docs/lifecycle.md, "As found, as left"): the
# campaign's held-out targets commanded in closed loop through the earlier calibration's
# exported bundle of the model in use, before anything is adjusted. Its metrics are the
# core's rule; the open-loop runs of the campaign wait for it (acquire_inputs).
# Not in the group "campaign": the open-loop runs wait for it, so when a new reference
# calibration reruns it alone, a group holding it would hold a job that waits on a job
# outside the group that waits on it (Snakemake refuses such a DAG).


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
    conda:
        CONDA_ENV
    resources:
        mem_mb=400,
        runtime=1,
        rig=rig_slots,
    params:
        campaign=campaign_file,
        folder=lambda w, input: os.path.join(
            os.path.dirname(input.manifest), CAMPAIGN[w.campaign]["as_found"]["model"]
        ),
        digest=lambda w: digest(
            [
                rig_digest("as_found")(w),
                CAMPAIGN[w.campaign]["as_found"],
                CAMPAIGN[w.campaign]["validation"]["heldout"],
                CAMPAIGN[w.campaign]["validation"]["dwell_s"],
                CAMPAIGN[w.campaign]["identification"],
            ]
        ),
    shell:
        "calflow acquire --campaign {params.campaign} --plan as_found"
        " --export {params.folder} --out {output.run} --truth {output.truth} > {log} 2>&1"
