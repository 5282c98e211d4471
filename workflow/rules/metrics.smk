# The metrics of a run (ISO 9283, ISO 230-2, the family's own): the runs each family's
# FamilyWorkflow.metrics_runs names.


rule metrics:
    input:
        run=layout.run("{campaign}", "{name}"),
    output:
        metrics=layout.metrics("{campaign}", "{name}"),
    log:
        layout.log("{campaign}", "metrics_{name}"),
    benchmark:
        layout.benchmark("{campaign}", "metrics_{name}")
    wildcard_constraints:
        name=METRICS_RUNS,
    group:
        "campaign"
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=200,
        runtime=1,
    params:
        **reads("metrics"),
        campaign=campaign_file,
    shell:
        "calflow metrics --campaign {params.campaign} --sections {params.sections:q} --run {input.run}"
        " --out {output.metrics} > {log} 2>&1"
