# Campaign summary, per-campaign report (HTML and PDF) and the cross-campaign index.

from calflow.configuration.reference import files as reference_files
from calflow.report.catalogue import listing_digest


rule summarise:
    input:
        files=lambda w: results_of(w.campaign),
        truth=summary_truth,
        budget=lambda w: budget_file(w.campaign),
        reference=lambda w: reference_files(CAMPAIGN[w.campaign]),
    output:
        summary=report(
            layout.summary("{campaign}"),
            caption="../report/summary.rst",
            category="Summaries",
            labels={"campaign": "{campaign}"},
        ),
    log:
        layout.log("{campaign}", "summarise"),
    benchmark:
        layout.benchmark("{campaign}", "summarise")
    group:
        "campaign"
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=1300,
        runtime=10,
    params:
        # the summary reads the whole campaign (each family's its own sections, the stage and
        # the reference values): its step declares every section, handed to it and digested
        **reads("summarise"),
        campaign=campaign_file,
        truth=lambda w, input: f"--truth {input.truth}" if input.truth else "",
        budget=lambda w, input: f"--budget {input.budget}" if input.budget else "",
        settings=lambda w: shlex.quote(certificate_settings(w.campaign)),
    shell:
        "calflow summarise --campaign {params.campaign} --sections {params.sections:q}"
        " --files {input.files}"
        " {params.truth} {params.budget} --settings {params.settings}"
        " --out {output.summary} > {log} 2>&1"


rule report:
    input:
        summary=layout.summary("{campaign}"),
        files=lambda w: report_files(w.campaign),
    output:
        html=report(
            layout.report("{campaign}"),
            caption="../report/campaign_report.rst",
            category="Campaign reports",
            labels={"campaign": "{campaign}", "format": "HTML"},
        ),
        pdf=report(
            layout.report("{campaign}", "pdf"),
            caption="../report/campaign_pdf.rst",
            category="Campaign reports",
            labels={"campaign": "{campaign}", "format": "PDF"},
        ),
    log:
        layout.log("{campaign}", "report"),
    benchmark:
        layout.benchmark("{campaign}", "report")
    group:
        "campaign"
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=800,
        runtime=2,
    params:
        # the report shows the whole campaign (its settings beside the results): its step
        # declares every section, handed to it and digested
        **reads("report"),
        campaign=campaign_file,
    shell:
        "calflow report --campaign {params.campaign} --sections {params.sections:q}"
        " --summary {input.summary}"
        " --files {input.files} --html {output.html} --pdf {output.pdf} > {log} 2>&1"


rule index:
    input:
        summaries=expand(layout.summary("{campaign}"), campaign=CAMPAIGNS),
        reports=expand(layout.report("{campaign}"), campaign=CAMPAIGNS),
        histories=expand(layout.history("{stage}"), stage=HISTORIES),
    output:
        report(
            layout.index(),
            caption="../report/index.rst",
            category="Index",
            labels={"page": "all campaigns"},
        ),
    log:
        layout.results("logs", "index.log"),
    benchmark:
        layout.results("benchmarks", "index.tsv")
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=300,
        runtime=1,
    params:
        # the other campaigns on disk (another run's, deleted, failed): a change reruns the index
        on_disk=lambda w: digest(
            [
                code_digest("index"),
                listing_digest(layout.results(), tuple(CAMPAIGNS)),
            ]
        ),
        campaign_dir=CAMPAIGN_DIR,
        results=lambda w: layout.results(),
        reports=lambda w: layout.reports(),
    shell:
        "calflow index --results {params.results} --reports {params.reports}"
        " --campaign-dir {params.campaign_dir} --out {output} > {log} 2>&1"
