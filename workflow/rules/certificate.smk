# A campaign's certificate: its results with U, the stage's decision rule and decisions
# (summary keys written by the summarise rule; docs/certificate.md).


rule certificate:
    input:
        summary=layout.summary("{campaign}"),
    output:
        html=layout.certificate("{campaign}"),
        pdf=layout.certificate("{campaign}", "pdf"),
    log:
        layout.log("{campaign}", "certificate"),
    benchmark:
        layout.benchmark("{campaign}", "certificate")
    group:
        "campaign"
    conda:
        "../envs/calflow.yaml"
    resources:
        mem_mb=400,
        runtime=1,
    params:
        campaign=campaign_file,
        digest=lambda w: digest([code_digest("certificate", robot(w))]),
    shell:
        "calflow certificate --campaign {params.campaign} --summary {input.summary}"
        " --html {output.html} --pdf {output.pdf} > {log} 2>&1"
