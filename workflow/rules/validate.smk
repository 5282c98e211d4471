# Validation on the rig through each model's inverse, and its ISO 9283 metrics.


rule acquire_validation:
    input:
        model="results/{campaign}/models/{model}.nc",
    output:
        run="results/{campaign}/runs/validation_{model}.nc",
    params:
        campaign=campaign_file,
        digest=section("robot", "seed", "start", "rig", "validation"),
    log:
        "results/{campaign}/logs/acquire_validation_{model}.log",
    resources:
        mem_mb=1000,
    shell:
        "calflow acquire --campaign {params.campaign} --plan validation"
        " --model {input.model} --out {output.run} > {log} 2>&1"


rule metrics:
    input:
        run="results/{campaign}/runs/validation_{model}.nc",
    output:
        metrics="results/{campaign}/metrics/validation_{model}.nc",
    params:
        campaign=campaign_file,
        digest=section("validation"),
    log:
        "results/{campaign}/logs/metrics_{model}.log",
    resources:
        mem_mb=1000,
    shell:
        "calflow metrics --campaign {params.campaign} --run {input.run}"
        " --out {output.metrics} > {log} 2>&1"
