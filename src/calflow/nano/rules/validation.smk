# Validation of the nano stages: one run commanding every model's test (Sec. 5.3.3, 5.4.2).


rule acquire_validation_tests:
    input:
        models=lambda w: expand(
            layout.model("{c}", "{m}"),
            c=w.campaign,
            m=models_of(CAMPAIGN[w.campaign]),
        ),
    output:
        run=layout.run("{campaign}", "validation"),
        truth=layout.truth("{campaign}", "validation"),
    log:
        layout.log("{campaign}", "acquire_validation"),
    benchmark:
        layout.benchmark("{campaign}", "acquire_validation")
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=400,
        runtime=6,
        rig=rig_slots,
    params:
        **reads("acquire", "validation"),
        campaign=campaign_file,
        models=lambda w, input: " ".join(f"--model {m}" for m in input.models),
    shell:
        "calflow acquire --campaign {params.campaign} --sections {params.sections:q} --plan validation"
        " {params.models} --out {output.run} --truth {output.truth} > {log} 2>&1"
