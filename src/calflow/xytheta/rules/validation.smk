# XYΘ validation on the rig through each model's inverse kinematics on the reference
# targets (the held-out targets are the core's rule), and the error budget's replays.


ruleorder: acquire_validation_heldout > acquire_validation_model


rule acquire_validation_model:
    input:
        model=layout.model("{campaign}", "{model}"),
    output:
        run=layout.run("{campaign}", "validation_{model}"),
        truth=layout.truth("{campaign}", "validation_{model}"),
    log:
        layout.log("{campaign}", "acquire_validation_{model}"),
    benchmark:
        layout.benchmark("{campaign}", "acquire_validation_{model}")
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=300,
        runtime=1,
        rig=rig_slots,
    params:
        # the reference targets' plan: the validation section but its held-out targets
        **reads("acquire", reference_validation),
        campaign=campaign_file,
    shell:
        "calflow acquire --campaign {params.campaign} --sections {params.sections:q} --plan validation"
        " --model {input.model} --out {output.run} --truth {output.truth} > {log} 2>&1"


rule error_budget:
    output:
        budget=layout.truth("{campaign}", "error_budget"),
    log:
        layout.log("{campaign}", "error_budget"),
    benchmark:
        layout.benchmark("{campaign}", "error_budget")
    group:
        "campaign"
    conda:
        CONDA_ENV
    threads: 2
    resources:
        mem_mb=700,
        runtime=5,
    params:
        # the budget's replays read the rig, the calibration's sections, the held-out targets
        **reads("error-budget"),
        campaign=campaign_file,
    shell:
        "calflow error-budget --campaign {params.campaign} --sections {params.sections:q} --jobs {threads}"
        " --out {output.budget} > {log} 2>&1"


# The camera and decoder of a rig that reads through images, on rendered frames: the
# report's measurement-system section (calflow.instruments.bench).
rule instrument_bench:
    output:
        bench=layout.metrics("{campaign}", "instrument"),
        throughput=layout.campaign(
            "{campaign}", "benchmarks", "instrument_throughput.json"
        ),
    log:
        layout.log("{campaign}", "instrument_bench"),
    benchmark:
        layout.benchmark("{campaign}", "instrument_bench")
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=300,
        runtime=1,
    params:
        **reads("instrument-bench"),
        campaign=campaign_file,
    shell:
        "calflow instrument-bench --campaign {params.campaign} --sections {params.sections:q} --out {output.bench}"
        " --throughput {output.throughput} > {log} 2>&1"
