# Identification of each calibration model of a campaign (its family's models and inputs).


rule identify:
    input:
        unpack(identify_inputs),
    output:
        model=layout.model("{campaign}", "{model}"),
    log:
        layout.log("{campaign}", "identify_{model}"),
    benchmark:
        layout.benchmark("{campaign}", "identify_{model}")
    group:
        "campaign"
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=400,
        runtime=1,
    params:
        campaign=campaign_file,
        args=identify_args,
        digest=identify_digest,
    shell:
        "calflow identify --campaign {params.campaign} --model-name {wildcards.model}"
        " {params.args} --out {output.model} > {log} 2>&1"
