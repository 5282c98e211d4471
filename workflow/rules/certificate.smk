# A campaign's certificate: its results with U, the stage's decision rule and decisions
# (summary keys written by the summarise rule; docs/certificate.md).


rule certificate:
    input:
        summary=layout.summary("{campaign}"),
    output:
        html=layout.certificate("{campaign}"),
        pdf=layout.certificate("{campaign}", "pdf"),
        xml=layout.certificate("{campaign}", "xml"),
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
        # the method states the campaign's plan (its digest): the step reads every section
        **reads("certificate"),
        campaign=campaign_file,
        laboratory=lambda w: shlex.quote(laboratory_settings()),
        item=lambda w: shlex.quote(item_settings(w.campaign)),
        # where the signing key is (never the key): a key given or gone remakes the documents
        signing_key=lambda w: os.environ.get("CALFLOW_SIGNING_KEY")
        or (config.get("laboratory") or {}).get("signing_key")
        or "",
    shell:
        "calflow certificate --campaign {params.campaign} --sections {params.sections:q}"
        " --summary {input.summary} --laboratory {params.laboratory} --item {params.item}"
        " --html {output.html} --pdf {output.pdf} --xml {output.xml} > {log} 2>&1"
