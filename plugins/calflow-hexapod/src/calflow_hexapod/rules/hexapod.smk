# The hexapod's own steps: the five ISO 9283 poses P1-P5 commanded through each model (ISO
# 9283:1998 7.2), for campaigns with an iso9283 section; and, on a simulated rig with
# validation.heldout.error_budget, the error budget by effect (replays on the rig's truth:
# reports only). Uses what calflow's common.smk defines: CAMPAIGN, campaign_file, section,
# rig_digest, rig_slots, digest, CONDA_ENV.


rule acquire_hexapod_iso9283:
    input:
        model="results/{campaign}/models/{model}.nc",
    output:
        run="results/{campaign}/runs/iso9283_{model}.nc",
        truth="results/{campaign}/truth/iso9283_{model}.json",
    log:
        "results/{campaign}/logs/acquire_iso9283_{model}.log",
    benchmark:
        "results/{campaign}/benchmarks/acquire_iso9283_{model}.tsv"
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,
        rig=rig_slots,
    params:
        campaign=campaign_file,
        digest=lambda w: digest(
            [
                rig_digest(f"iso9283_{w.model}")(w),
                CAMPAIGN[w.campaign].get("iso9283"),
                CAMPAIGN[w.campaign]["validation"]["dwell_s"],
            ]
        ),
    shell:
        "calflow acquire --campaign {params.campaign} --plan iso9283"
        " --model {input.model} --out {output.run} --truth {output.truth} > {log} 2>&1"


rule hexapod_error_budget:
    output:
        budget="results/{campaign}/truth/hexapod_error_budget.json",
    log:
        "results/{campaign}/logs/hexapod_error_budget.log",
    benchmark:
        "results/{campaign}/benchmarks/hexapod_error_budget.tsv"
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=2000,
    params:
        campaign=campaign_file,
        digest=section(
            "hexapod-error-budget",
            "seed",
            "start",
            "rig",
            "identification",
            "models",
            "validation",
        ),
    shell:
        "calflow hexapod-error-budget --campaign {params.campaign}"
        " --out {output.budget} > {log} 2>&1"


# Each model's identified geometry exported as a bundle (bundle.json, geometry.nc), then the
# held-out targets commanded again through the bundle's Compensator loaded from those files
# (closed loop); the core metrics rule scores the run like the held-out one.
rule hexapod_export:
    input:
        model="results/{campaign}/models/{model}.nc",
    output:
        bundle="results/{campaign}/export/{model}/bundle.json",
    log:
        "results/{campaign}/logs/hexapod_export_{model}.log",
    benchmark:
        "results/{campaign}/benchmarks/hexapod_export_{model}.tsv"
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,
    params:
        campaign=campaign_file,
        folder=lambda w, output: os.path.dirname(output.bundle),
        digest=section("hexapod-export"),
    shell:
        "calflow hexapod-export --campaign {params.campaign} --model {input.model}"
        " --out {params.folder} > {log} 2>&1"


rule acquire_hexapod_closed_loop:
    input:
        model="results/{campaign}/models/{model}.nc",
        bundle="results/{campaign}/export/{model}/bundle.json",
    output:
        run="results/{campaign}/runs/closed_loop_{model}.nc",
        truth="results/{campaign}/truth/closed_loop_{model}.json",
    log:
        "results/{campaign}/logs/acquire_closed_loop_{model}.log",
    benchmark:
        "results/{campaign}/benchmarks/acquire_closed_loop_{model}.tsv"
    group:
        "campaign"
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,
        rig=rig_slots,
    params:
        campaign=campaign_file,
        folder=lambda w, input: os.path.dirname(input.bundle),
        digest=lambda w: digest(
            [
                rig_digest(f"closed_loop_{w.model}")(w),
                CAMPAIGN[w.campaign]["validation"]["heldout"],
                CAMPAIGN[w.campaign]["validation"]["dwell_s"],
                CAMPAIGN[w.campaign]["identification"],
            ]
        ),
    shell:
        "calflow acquire --campaign {params.campaign} --plan validation_export"
        " --model {input.model} --bundle {params.folder} --out {output.run}"
        " --truth {output.truth} > {log} 2>&1"
