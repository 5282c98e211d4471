# A stage's life: the history of every stage with campaigns in the run (docs/lifecycle.md).


wildcard_constraints:
    stage="[A-Za-z0-9][A-Za-z0-9_-]*",


rule stage_history:
    input:
        summaries=lambda w: [f"results/{n}/summary.json" for n in STAGES[w.stage]],
    output:
        "results/stages/{stage}/history.json",
    log:
        "results/stages/{stage}/logs/history.log",
    benchmark:
        "results/stages/{stage}/benchmarks/history.tsv"
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=1000,
    params:
        campaigns=stage_campaign_files,
        settings=lambda w: shlex.quote(stage_settings(w)),
        digest=stage_digest,
    shell:
        "calflow history --stage {wildcards.stage} --campaigns {params.campaigns}"
        " --summaries {input.summaries} --settings {params.settings} --out {output} > {log} 2>&1"


rule stage_report:
    input:
        "results/stages/{stage}/history.json",
    output:
        html="reports/stages/{stage}/history.html",
        pdf="reports/stages/{stage}/history.pdf",
    log:
        "results/stages/{stage}/logs/report.log",
    benchmark:
        "results/stages/{stage}/benchmarks/report.tsv"
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=2000,
    params:
        digest=lambda w: digest(
            [code_digest("history-report", CAMPAIGN[STAGES[w.stage][0]]["robot"])]
        ),
    shell:
        "calflow history-report --history {input} --html {output.html}"
        " --pdf {output.pdf} > {log} 2>&1"
