# An interim check of a stage (docs/lifecycle.md): the targets commanded in closed loop
# through the reference calibration's exported bundle. Its metrics, summary and report are
# the core's rules (the family's workflow names the files).


rule acquire_interim_check:
    input:
        manifest=interim_export,
        reference_run=interim_reference_run,
    output:
        run=layout.run("{campaign}", "interim_check"),
        truth=layout.truth("{campaign}", "interim_check"),
    log:
        layout.log("{campaign}", "acquire_interim_check"),
    benchmark:
        layout.benchmark("{campaign}", "acquire_interim_check")
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=300,
        runtime=1,
        rig=rig_slots,
    params:
        # the sequential test stops at the campaign's tolerance unless the check gives its own
        **reads("acquire", "interim_check", "tolerance_um"),
        campaign=campaign_file,
        folder=lambda w, input: os.path.join(
            os.path.dirname(input.manifest),
            CAMPAIGN[w.campaign]["interim_check"]["model"],
        ),
    shell:
        "calflow acquire --campaign {params.campaign} --sections {params.sections:q} --plan interim_check"
        " --export {params.folder} --out {output.run} --truth {output.truth} > {log} 2>&1"
