# Held-out validation: each model commands, through its inverse, targets no identification
# saw (the family's plan validation_heldout draws them from the campaign's
# validation.heldout section).


rule acquire_validation_heldout:
    input:
        model=layout.model("{campaign}", "{model}"),
    output:
        run=layout.run("{campaign}", "validation_heldout_{model}"),
        truth=layout.truth("{campaign}", "validation_heldout_{model}"),
    log:
        layout.log("{campaign}", "acquire_validation_heldout_{model}"),
    benchmark:
        layout.benchmark("{campaign}", "acquire_validation_heldout_{model}")
    group:
        "campaign"
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=400,
        runtime=1,
        rig=rig_slots,
    params:
        **reads("acquire", "validation.heldout", "validation.dwell_s", "identification"),
        campaign=campaign_file,
    shell:
        "calflow acquire --campaign {params.campaign} --sections {params.sections:q} --plan validation_heldout"
        " --model {input.model} --out {output.run} --truth {output.truth} > {log} 2>&1"
