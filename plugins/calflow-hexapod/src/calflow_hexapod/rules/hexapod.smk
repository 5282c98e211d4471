# The hexapod's own steps: the five ISO 9283 poses P1-P5 commanded through each model (ISO
# 9283:1998 7.2), for campaigns with an iso9283 section; and, on a simulated rig with
# validation.heldout.error_budget, the error budget by effect (replays on the rig's truth:
# reports only). Uses what calflow's common.smk defines: CAMPAIGN, campaign_file, reads,
# rig_slots, CONDA_ENV.


rule acquire_hexapod_iso9283:
    input:
        model=layout.model("{campaign}", "{model}"),
    output:
        run=layout.run("{campaign}", "iso9283_{model}"),
        truth=layout.truth("{campaign}", "iso9283_{model}"),
    log:
        layout.log("{campaign}", "acquire_iso9283_{model}"),
    benchmark:
        layout.benchmark("{campaign}", "acquire_iso9283_{model}")
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=300,
        runtime=1,
        rig=rig_slots,
    params:
        # the test cube's poses are mapped by the nominal model with identification.initial's frames
        **reads("acquire", "iso9283", "validation.dwell_s", "identification.initial"),
        campaign=campaign_file,
    shell:
        "calflow acquire --campaign {params.campaign} --sections {params.sections:q} --plan iso9283"
        " --model {input.model} --out {output.run} --truth {output.truth} > {log} 2>&1"


rule hexapod_error_budget:
    output:
        budget=layout.truth("{campaign}", "hexapod_error_budget"),
    log:
        layout.log("{campaign}", "hexapod_error_budget"),
    benchmark:
        layout.benchmark("{campaign}", "hexapod_error_budget")
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=400,
        runtime=2,
    params:
        **reads("hexapod-error-budget"),
        campaign=campaign_file,
    shell:
        "calflow hexapod-error-budget --campaign {params.campaign} --sections {params.sections:q}"
        " --out {output.budget} > {log} 2>&1"


# Each model's identified geometry exported as a bundle (bundle.json, geometry.nc), then the
# held-out targets commanded again through the bundle's Compensator loaded from those files
# (closed loop); the core metrics rule scores the run like the held-out one.
rule hexapod_export:
    input:
        model=layout.model("{campaign}", "{model}"),
    output:
        bundle=layout.campaign("{campaign}", "export", "{model}", "bundle.json"),
    log:
        layout.log("{campaign}", "hexapod_export_{model}"),
    benchmark:
        layout.benchmark("{campaign}", "hexapod_export_{model}")
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=200,
        runtime=1,
    params:
        **reads("hexapod-export"),
        campaign=campaign_file,
        folder=lambda w, output: os.path.dirname(output.bundle),
    shell:
        "calflow hexapod-export --campaign {params.campaign} --sections {params.sections:q} --model {input.model}"
        " --out {params.folder} > {log} 2>&1"


rule acquire_hexapod_closed_loop:
    input:
        model=layout.model("{campaign}", "{model}"),
        bundle=layout.campaign("{campaign}", "export", "{model}", "bundle.json"),
    output:
        run=layout.run("{campaign}", "closed_loop_{model}"),
        truth=layout.truth("{campaign}", "closed_loop_{model}"),
    log:
        layout.log("{campaign}", "acquire_closed_loop_{model}"),
    benchmark:
        layout.benchmark("{campaign}", "acquire_closed_loop_{model}")
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=300,
        runtime=1,
        rig=rig_slots,
    params:
        **reads("acquire", "validation.heldout", "validation.dwell_s", "identification"),
        campaign=campaign_file,
        folder=lambda w, input: os.path.dirname(input.bundle),
    shell:
        "calflow acquire --campaign {params.campaign} --sections {params.sections:q} --plan validation_export"
        " --model {input.model} --bundle {params.folder} --out {output.run}"
        " --truth {output.truth} > {log} 2>&1"
