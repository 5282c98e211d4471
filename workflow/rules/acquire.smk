# Acquisition: a plan run on the campaign's rig becomes a run dataset.


rule acquire:
    input:
        unpack(acquire_inputs),
    output:
        run="results/{campaign}/runs/{run}.nc",
        truth="results/{campaign}/truth/{run}.json",
    log:
        "results/{campaign}/logs/acquire_{run}.log",
    benchmark:
        "results/{campaign}/benchmarks/acquire_{run}.tsv"
    group:
        "campaign"
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=400,
        runtime=1,
        rig=rig_slots,
    params:
        campaign=campaign_file,
        digest=lambda w: digest([rig_digest(w.run)(w), plan_section(w)]),
        args=input_args,
    shell:
        "calflow acquire --campaign {params.campaign} --plan {wildcards.run} {params.args}"
        " --out {output.run} --truth {output.truth} > {log} 2>&1"


# A run recorded as camera frames (rig.options.recordings.<run>: {format: frames, ...}) is
# decoded into a run dataset first; the acquire rule's replay rig serves it. A changed
# decoder reruns this rule (its digest), the frames stay in their files.
rule decode_frames:
    input:
        frames_of,
    output:
        run="results/{campaign}/decoded/{run}.nc",
    log:
        "results/{campaign}/logs/decode_frames_{run}.log",
    benchmark:
        "results/{campaign}/benchmarks/decode_frames_{run}.tsv"
    group:
        "campaign"
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=600,
        runtime=5,
    params:
        campaign=campaign_file,
        digest=decode_digest,
    shell:
        "calflow decode-run --campaign {params.campaign} --run {wildcards.run}"
        " --out {output.run} > {log} 2>&1"
