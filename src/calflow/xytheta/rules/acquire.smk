# XYΘ runs beside the core's open-loop ones: the square and random-points tests with and
# without table compensation (Sec. 4.4.2), and the angle-residual runs of Models IV/V.


wildcard_constraints:
    test="square|random_points",
    comp="none|linear|cubic",


rule acquire_xy_test:
    input:
        luts=lambda w: ([] if w.comp == "none" else layout.luts(w.campaign)),
    output:
        run=layout.run("{campaign}", "{test}_{comp}"),
        truth=layout.truth("{campaign}", "{test}_{comp}"),
    log:
        layout.log("{campaign}", "acquire_{test}_{comp}"),
    benchmark:
        layout.benchmark("{campaign}", "acquire_{test}_{comp}")
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=300,
        runtime=1,
        rig=rig_slots,
    params:
        **reads("acquire", "xy_tests"),
        campaign=campaign_file,
        luts=lambda w, input: f"--luts {input.luts}" if input.luts else "",
    shell:
        "calflow acquire --campaign {params.campaign} --sections {params.sections:q} --plan {wildcards.test}"
        " --compensation {wildcards.comp} {params.luts} --out {output.run}"
        " --truth {output.truth} > {log} 2>&1"


rule acquire_angle_residuals:
    input:
        model=layout.model("{campaign}", "{model}"),
    output:
        run=layout.run("{campaign}", "angle_residuals_{model}"),
        truth=layout.truth("{campaign}", "angle_residuals_{model}"),
    log:
        layout.log("{campaign}", "acquire_angle_residuals_{model}"),
    benchmark:
        layout.benchmark("{campaign}", "acquire_angle_residuals_{model}")
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=400,
        runtime=1,
        rig=rig_slots,
    params:
        # its positions are drawn over the identification's workspace
        **reads("acquire", "angle_residuals", "identification"),
        campaign=campaign_file,
    shell:
        "calflow acquire --campaign {params.campaign} --sections {params.sections:q} --plan angle_residuals"
        " --model {input.model} --out {output.run} --truth {output.truth} > {log} 2>&1"
