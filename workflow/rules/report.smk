# Campaign summary, per-campaign report (HTML and PDF) and the cross-campaign index.

from calflow.reference import files as reference_files
from calflow.report.catalogue import listing_digest


rule summarise:
    input:
        files=lambda w: results_of(w.campaign),
        truth=summary_truth,
        budget=lambda w: budget_file(w.campaign),
        reference=lambda w: reference_files(CAMPAIGN[w.campaign]),
    output:
        summary=report(
            "results/{campaign}/summary.json",
            caption="../report/summary.rst",
            category="Summaries",
            labels={"campaign": "{campaign}"},
        ),
    log:
        "results/{campaign}/logs/summarise.log",
    benchmark:
        "results/{campaign}/benchmarks/summarise.tsv"
    group:
        "campaign"
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=400,
        runtime=1,
    params:
        campaign=campaign_file,
        truth=lambda w, input: f"--truth {input.truth}" if input.truth else "",
        budget=lambda w, input: f"--budget {input.budget}" if input.budget else "",
        settings=lambda w: shlex.quote(certificate_settings(w.campaign)),
        digest=section(
            "summarise",
            "description",
            "robot",
            "seed",
            "rig",
            "uncertainty",
            "reference",
        ),
    shell:
        "calflow summarise --campaign {params.campaign} --files {input.files}"
        " {params.truth} {params.budget} --settings {params.settings}"
        " --out {output.summary} > {log} 2>&1"


rule report:
    input:
        summary="results/{campaign}/summary.json",
        files=lambda w: report_files(w.campaign),
    output:
        html=report(
            "reports/{campaign}/report.html",
            caption="../report/campaign_report.rst",
            category="Campaign reports",
            labels={"campaign": "{campaign}", "format": "HTML"},
        ),
        pdf=report(
            "reports/{campaign}/report.pdf",
            caption="../report/campaign_pdf.rst",
            category="Campaign reports",
            labels={"campaign": "{campaign}", "format": "PDF"},
        ),
    log:
        "results/{campaign}/logs/report.log",
    benchmark:
        "results/{campaign}/benchmarks/report.tsv"
    group:
        "campaign"
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=600,
        runtime=2,
    params:
        campaign=campaign_file,
        digest=lambda w: digest([code_digest("report", robot(w)), CAMPAIGN[w.campaign]]),
    shell:
        "calflow report --campaign {params.campaign} --summary {input.summary}"
        " --files {input.files} --html {output.html} --pdf {output.pdf} > {log} 2>&1"


rule index:
    input:
        summaries=expand("results/{campaign}/summary.json", campaign=CAMPAIGNS),
        reports=expand("reports/{campaign}/report.html", campaign=CAMPAIGNS),
        histories=expand("results/stages/{stage}/history.json", stage=HISTORIES),
    output:
        report(
            "reports/index.html",
            caption="../report/index.rst",
            category="Index",
            labels={"page": "all campaigns"},
        ),
    log:
        "results/logs/index.log",
    benchmark:
        "results/benchmarks/index.tsv"
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=200,
        runtime=1,
    params:
        # the other campaigns on disk (another run's, deleted, failed): a change reruns the index
        on_disk=lambda w: digest(
            [
                code_digest("index"),
                listing_digest("results", tuple(CAMPAIGNS)),
            ]
        ),
        campaign_dir=CAMPAIGN_DIR,
    shell:
        "calflow index --results results --reports reports"
        " --campaign-dir {params.campaign_dir} --out {output} > {log} 2>&1"
