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
        mem_mb=300,
        runtime=1,
    params:
        **reads("identify", identify_sections),
        campaign=campaign_file,
        args=identify_args,
    shell:
        "calflow identify --campaign {params.campaign} --sections {params.sections:q} --model-name {wildcards.model}"
        " {params.args} --out {output.model} > {log} 2>&1"
