# Export of each XYΘ model to controllers and users' code, and its closed-loop check on
# the rig (docs/export.md): the held-out targets commanded through the exported files.
# The export takes every model in one job (a job's time is mostly its imports).


rule export_models:
    input:
        models=lambda w: expand(
            layout.model("{c}", "{m}"),
            c=w.campaign,
            m=models_of(CAMPAIGN[w.campaign]),
        ),
    output:
        manifest=layout.campaign("{campaign}", "export", "manifest.json"),
    log:
        layout.log("{campaign}", "export"),
    benchmark:
        layout.benchmark("{campaign}", "export")
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=300,
        runtime=1,
    params:
        **reads("export"),
        campaign=campaign_file,
        folder=lambda w, output: os.path.dirname(output.manifest),
    shell:
        "calflow export --campaign {params.campaign} --sections {params.sections:q} --model {input.models}"
        " --out {params.folder} > {log} 2>&1"


rule acquire_validation_export:
    input:
        model=layout.model("{campaign}", "{model}"),
        manifest=layout.campaign("{campaign}", "export", "manifest.json"),
    output:
        run=layout.run("{campaign}", "export_{model}"),
    log:
        layout.log("{campaign}", "acquire_export_{model}"),
    benchmark:
        layout.benchmark("{campaign}", "acquire_export_{model}")
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=400,
        runtime=1,
        rig=rig_slots,
    params:
        **reads("acquire", "validation.heldout", "validation.dwell_s", "identification"),
        campaign=campaign_file,
        folder=lambda w, input: os.path.join(os.path.dirname(input.manifest), w.model),
    shell:
        "calflow acquire --campaign {params.campaign} --sections {params.sections:q} --plan validation_export"
        " --model {input.model} --export {params.folder} --out {output.run} > {log} 2>&1"


rule export_verify:
    input:
        run=layout.run("{campaign}", "export_{model}"),
        heldout=layout.metrics("{campaign}", "validation_heldout_{model}"),
    output:
        metrics=layout.metrics("{campaign}", "export_{model}"),
    log:
        layout.log("{campaign}", "export_verify_{model}"),
    benchmark:
        layout.benchmark("{campaign}", "export_verify_{model}")
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=200,
        runtime=1,
    params:
        **reads("export-verify"),
        campaign=campaign_file,
    shell:
        "calflow export-verify --campaign {params.campaign} --sections {params.sections:q} --run {input.run}"
        " --heldout {input.heldout} --out {output.metrics} > {log} 2>&1"
