# Held-out validation: each model commands, through its inverse, targets no identification
# saw (the family's plan validation_heldout draws them from the campaign's
# validation.heldout section).


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
    group:
        "campaign"
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
