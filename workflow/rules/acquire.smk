# Acquisition: a plan run on the campaign's rig becomes a run dataset.


rule acquire:
    input:
        unpack(acquire_inputs),
    output:
        run=layout.run("{campaign}", "{run}"),
        truth=layout.truth("{campaign}", "{run}"),
    log:
        layout.log("{campaign}", "acquire_{run}"),
    benchmark:
        layout.benchmark("{campaign}", "acquire_{run}")
    group:
        "campaign"
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=400,
        runtime=1,
        rig=rig_slots,
    params:
        **reads("acquire", plan_section),
        campaign=campaign_file,
        args=input_args,
    shell:
        "calflow acquire --campaign {params.campaign} --sections {params.sections:q} --plan {wildcards.run}"
        " {params.args}"
        " --out {output.run} --truth {output.truth} > {log} 2>&1"


# A run recorded as camera frames (rig.options.recordings.<run>: {format: frames, ...}) is
# decoded into a run dataset first; the acquire rule's replay rig serves it. A changed
# decoder reruns this rule (its digest), the frames stay in their files.
rule decode_frames:
    input:
        frames_of,
    output:
        run=layout.decoded("{campaign}", "{run}"),
    log:
        layout.log("{campaign}", "decode_frames_{run}"),
    benchmark:
        layout.benchmark("{campaign}", "decode_frames_{run}")
    group:
        "campaign"
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=600,
        runtime=5,
    params:
        **reads("decode-run"),
        campaign=campaign_file,
        frames=frames_digest,
    shell:
        "calflow decode-run --campaign {params.campaign} --sections {params.sections:q} --run {wildcards.run}"
        " --out {output.run} > {log} 2>&1"
