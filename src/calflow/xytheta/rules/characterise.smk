# Error characterisation of the XY stages (Sec. 4.4.1) and the observability study (Fig. 4.21).


rule characterise:
    input:
        x=layout.run("{campaign}", "characterisation_x"),
        y=layout.run("{campaign}", "characterisation_y"),
    output:
        luts=layout.luts("{campaign}", "position"),
    log:
        layout.log("{campaign}", "characterise"),
    benchmark:
        layout.benchmark("{campaign}", "characterise")
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=200,
        runtime=1,
    params:
        **reads("characterise"),
        campaign=campaign_file,
    shell:
        "calflow characterise --campaign {params.campaign} --sections {params.sections:q}"
        " --x {input.x} --y {input.y}"
        " --out {output.luts} > {log} 2>&1"


rule observability:
    output:
        layout.metrics("{campaign}", "observability"),
    log:
        layout.log("{campaign}", "observability"),
    benchmark:
        layout.benchmark("{campaign}", "observability")
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=200,
        runtime=1,
    params:
        **reads("observability"),
        campaign=campaign_file,
    shell:
        "calflow observability --campaign {params.campaign} --sections {params.sections:q}"
        " --out {output} > {log} 2>&1"


rule design_study:
    output:
        layout.metrics("{campaign}", "design_study"),
    log:
        layout.log("{campaign}", "design_study"),
    benchmark:
        layout.benchmark("{campaign}", "design_study")
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,
    params:
        **reads("design-study"),
        campaign=campaign_file,
    shell:
        "calflow design-study --campaign {params.campaign} --sections {params.sections:q}"
        " --out {output} > {log} 2>&1"
