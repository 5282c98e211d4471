# Validation on the rig through the models' inverse kinematics, and the metrics of each run.


ruleorder: acquire_validation_heldout > acquire_validation_model


rule acquire_validation_model:
    input:
        model="results/{campaign}/models/{model}.nc",
    output:
        run="results/{campaign}/runs/validation_{model}.nc",
        truth="results/{campaign}/truth/validation_{model}.json",
    log:
        "results/{campaign}/logs/acquire_validation_{model}.log",
    benchmark:
        "results/{campaign}/benchmarks/acquire_validation_{model}.tsv"
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=400,
        runtime=1,
        rig=rig_slots,
    params:
        campaign=campaign_file,
        digest=lambda w: digest(
            [
                rig_digest(f"validation_{w.model}")(w),
                reference_validation(w),
            ]
        ),
    shell:
        "calflow acquire --campaign {params.campaign} --plan validation"
        " --model {input.model} --out {output.run} --truth {output.truth} > {log} 2>&1"


rule acquire_validation_heldout:
    input:
        model="results/{campaign}/models/{model}.nc",
    output:
        run="results/{campaign}/runs/validation_heldout_{model}.nc",
        truth="results/{campaign}/truth/validation_heldout_{model}.json",
    log:
        "results/{campaign}/logs/acquire_validation_heldout_{model}.log",
    benchmark:
        "results/{campaign}/benchmarks/acquire_validation_heldout_{model}.tsv"
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=300,
        runtime=1,
        rig=rig_slots,
    params:
        campaign=campaign_file,
        digest=lambda w: digest(
            [
                rig_digest(f"validation_heldout_{w.model}")(w),
                CAMPAIGN[w.campaign]["validation"]["heldout"],
                CAMPAIGN[w.campaign]["validation"]["dwell_s"],
                CAMPAIGN[w.campaign]["identification"],
            ]
        ),
    shell:
        "calflow acquire --campaign {params.campaign} --plan validation_heldout"
        " --model {input.model} --out {output.run} --truth {output.truth} > {log} 2>&1"


rule error_budget:
    output:
        budget="results/{campaign}/truth/error_budget.json",
    log:
        "results/{campaign}/logs/error_budget.log",
    benchmark:
        "results/{campaign}/benchmarks/error_budget.tsv"
    conda:
        "../envs/calflow.yaml"
    threads: 2
    resources:
        mem_mb=900,
        runtime=2,
    params:
        campaign=campaign_file,
        digest=budget_digest,
    shell:
        "calflow error-budget --campaign {params.campaign} --jobs {threads}"
        " --out {output.budget} > {log} 2>&1"


rule acquire_validation_tests:
    input:
        models=lambda w: expand(
            "results/{c}/models/{m}.nc",
            c=w.campaign,
            m=nano_models(CAMPAIGN[w.campaign]),
        ),
    output:
        run="results/{campaign}/runs/validation.nc",
        truth="results/{campaign}/truth/validation.json",
    log:
        "results/{campaign}/logs/acquire_validation.log",
    benchmark:
        "results/{campaign}/benchmarks/acquire_validation.tsv"
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=400,
        runtime=2,
        rig=rig_slots,
    params:
        campaign=campaign_file,
        models=lambda w, input: " ".join(f"--model {m}" for m in input.models),
        digest=lambda w: digest(
            [rig_digest("validation")(w), CAMPAIGN[w.campaign]["validation"]]
        ),
    shell:
        "calflow acquire --campaign {params.campaign} --plan validation"
        " {params.models} --out {output.run} --truth {output.truth} > {log} 2>&1"


rule metrics:
    input:
        run="results/{campaign}/runs/{name}.nc",
    output:
        metrics="results/{campaign}/metrics/{name}.nc",
    log:
        "results/{campaign}/logs/metrics_{name}.log",
    benchmark:
        "results/{campaign}/benchmarks/metrics_{name}.tsv"
    wildcard_constraints:
        name="validation|validation_[A-Za-z0-9_]+|training|metrology|(square|random_points)_(none|linear|cubic)",
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=300,
        runtime=1,
    params:
        campaign=campaign_file,
        digest=section("metrics"),
    shell:
        "calflow metrics --campaign {params.campaign} --run {input.run}"
        " --out {output.metrics} > {log} 2>&1"
