# Campaign summary, per-campaign report (HTML and PDF) and the cross-campaign index.


rule summarise:
    input:
        models=lambda w: expand("results/{c}/models/{m}.nc", c=w.campaign, m=models_of(w)),
        metrics=lambda w: expand("results/{c}/metrics/validation_{m}.nc", c=w.campaign, m=models_of(w)),
        truth="results/{campaign}/truth/identification.json",
    output:
        summary="results/{campaign}/summary.json",
    params:
        campaign=campaign_file,
        models=lambda w: " ".join(f"{m}=results/{w.campaign}/models/{m}.nc" for m in models_of(w)),
        metrics=lambda w: " ".join(
            f"{m}=results/{w.campaign}/metrics/validation_{m}.nc" for m in models_of(w)
        ),
        digest=section("description", "robot", "seed", "rig", "models"),
    log:
        "results/{campaign}/logs/summarise.log",
    shell:
        "calflow summarise --campaign {params.campaign} --models {params.models}"
        " --metrics {params.metrics} --truth {input.truth} --out {output.summary} > {log} 2>&1"


rule report:
    input:
        summary="results/{campaign}/summary.json",
    output:
        html="reports/{campaign}/report.html",
        pdf="reports/{campaign}/report.pdf",
    params:
        campaign=campaign_file,
        digest=lambda w: digest([CALFLOW_VERSION, CAMPAIGN[w.campaign]]),
    log:
        "results/{campaign}/logs/report.log",
    shell:
        "calflow report --campaign {params.campaign} --summary {input.summary}"
        " --html {output.html} --pdf {output.pdf} > {log} 2>&1"


rule index:
    input:
        summaries=expand("results/{campaign}/summary.json", campaign=CAMPAIGNS),
    output:
        "reports/index.html",
    log:
        "results/logs/index.log",
    shell:
        "calflow index --summaries {input.summaries} --out {output} > {log} 2>&1"
