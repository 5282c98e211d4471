# The nano stages' step-response run: every move recorded from its start (ISO 9283 7.5, 7.6).


rule acquire_step_response:
    output:
        run=layout.run("{campaign}", "step_response"),
        truth=layout.truth("{campaign}", "step_response"),
    log:
        layout.log("{campaign}", "acquire_step_response"),
    benchmark:
        layout.benchmark("{campaign}", "acquire_step_response")
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=300,
        runtime=1,
        rig=rig_slots,
    params:
        **reads("acquire", "step_response"),
        campaign=campaign_file,
    shell:
        "calflow acquire --campaign {params.campaign} --sections {params.sections:q} --plan step_response"
        " --out {output.run} --truth {output.truth} > {log} 2>&1"
