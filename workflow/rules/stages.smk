# A stage's life: the history of every stage with campaigns in the run, from every campaign
# of the stage on disk (docs/lifecycle.md). Its files are updated in place: a failed job
# leaves the earlier history and its report as they were (Snakemake restores them).


wildcard_constraints:
    stage="[A-Za-z0-9][A-Za-z0-9_-]*",


rule stage_history:
    input:
        summaries=stage_summaries,
    output:
        update(layout.history("{stage}")),
    log:
        layout.stage("{stage}", "logs", "history.log"),
    benchmark:
        layout.stage("{stage}", "benchmarks", "history.tsv")
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=300,
        runtime=1,
    params:
        campaign_dir=CAMPAIGN_DIR,
        settings=lambda w: shlex.quote(stage_settings(w)),
        digest=stage_digest,
    shell:
        "calflow history --stage {wildcards.stage} --campaign-dir {params.campaign_dir}"
        " --summaries {input.summaries} --settings {params.settings} --out {output} > {log} 2>&1"


rule stage_report:
    input:
        layout.history("{stage}"),
    output:
        html=update(layout.stage_history("{stage}")),
        pdf=update(layout.stage_history("{stage}", "pdf")),
    log:
        layout.stage("{stage}", "logs", "report.log"),
    benchmark:
        layout.stage("{stage}", "benchmarks", "report.tsv")
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=600,
        runtime=1,
    params:
        digest=lambda w: digest([code_digest("history-report", stage_robot(w.stage))]),
    shell:
        "calflow history-report --history {input} --html {output.html}"
        " --pdf {output.pdf} > {log} 2>&1"
