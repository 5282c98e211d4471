# Identification of each calibration model from the identification run.


rule identify:
    input:
        run="results/{campaign}/runs/identification.nc",
    output:
        model="results/{campaign}/models/{model}.nc",
    params:
        campaign=campaign_file,
        digest=lambda w: digest(
            [CALFLOW_VERSION, CAMPAIGN[w.campaign]["identification"], CAMPAIGN[w.campaign]["models"][w.model]]
        ),
    log:
        "results/{campaign}/logs/identify_{model}.log",
    resources:
        mem_mb=1000,
    shell:
        "calflow identify --campaign {params.campaign} --model-name {wildcards.model}"
        " --run {input.run} --out {output.model} > {log} 2>&1"
