# Error characterisation of the XY stages (Sec. 4.4.1) and the observability study (Fig. 4.21).


rule characterise:
    input:
        x="results/{campaign}/runs/characterisation_x.nc",
        y="results/{campaign}/runs/characterisation_y.nc",
    output:
        luts="results/{campaign}/luts/position.nc",
    log:
        "results/{campaign}/logs/characterise.log",
    benchmark:
        "results/{campaign}/benchmarks/characterise.tsv"
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=300,
        runtime=1,
    params:
        campaign=campaign_file,
        digest=section("characterise"),
    shell:
        "calflow characterise --campaign {params.campaign} --x {input.x} --y {input.y}"
        " --out {output.luts} > {log} 2>&1"


rule observability:
    output:
        "results/{campaign}/metrics/observability.nc",
    log:
        "results/{campaign}/logs/observability.log",
    benchmark:
        "results/{campaign}/benchmarks/observability.tsv"
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=200,
        runtime=1,
    params:
        campaign=campaign_file,
        digest=section("observability", "seed", "identification", "observability"),
    shell:
        "calflow observability --campaign {params.campaign} --out {output} > {log} 2>&1"


rule design_study:
    output:
        "results/{campaign}/metrics/design_study.nc",
    log:
        "results/{campaign}/logs/design_study.log",
    benchmark:
        "results/{campaign}/benchmarks/design_study.tsv"
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,
    params:
        campaign=campaign_file,
        digest=section(
            "design-study", "seed", "rig", "identification", "models", "design_study"
        ),
    shell:
        "calflow design-study --campaign {params.campaign} --out {output} > {log} 2>&1"
