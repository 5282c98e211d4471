# Monte-Carlo studies: many simulated XYΘ campaigns over seeds × sensor noise ×
# identification poses (config/studies/<name>.yaml), one job per point or per batch of
# seeds (key seeds_per_job), then the aggregate and the study's page.
# Needs from common.smk: STUDIES (names) and STUDY (name -> calflow.xytheta.studies.montecarlo.load_study()).
from calflow.xytheta.studies import montecarlo as mc


wildcard_constraints:
    study="[A-Za-z0-9][A-Za-z0-9_-]*",
    seeds=r"\d+(-\d+)?",
    noise=r"[0-9][0-9.e+-]*",
    poses=r"\d+",


rule mc_point:
    output:
        point=layout.study_point("{study}", "{seeds}", "{noise}", "{poses}"),
    log:
        layout.study("{study}", "logs", "point_{seeds}_{noise}_{poses}.log"),
    benchmark:
        layout.study("{study}", "benchmarks", "point_{seeds}_{noise}_{poses}.tsv")
    group:
        "study_points"
    conda:
        CONDA_ENV
    resources:
        mem_mb=300,
        runtime=1,
    params:
        study=lambda w: STUDY[w.study]["file"],
        campaign_dir=CAMPAIGN_DIR,
        digest=lambda w: mc.point_digest(STUDY[w.study]),
    shell:
        "calflow mc-point --study {params.study} --campaign-dir {params.campaign_dir} --seed {wildcards.seeds}"
        " --noise {wildcards.noise} --poses {wildcards.poses} --out {output.point} > {log} 2>&1"


rule mc_aggregate:
    input:
        points=lambda w: mc.point_files(STUDY[w.study]),
    output:
        aggregate=layout.study("{study}", "aggregate.json"),
    log:
        layout.study("{study}", "logs", "aggregate.log"),
    benchmark:
        layout.study("{study}", "benchmarks", "aggregate.tsv")
    group:
        "study"
    conda:
        CONDA_ENV
    resources:
        mem_mb=300,
        runtime=1,
    params:
        study=lambda w: STUDY[w.study]["file"],
        campaign_dir=CAMPAIGN_DIR,
        digest=lambda w: mc.study_digest(STUDY[w.study]),
    shell:
        "calflow mc-aggregate --study {params.study} --campaign-dir {params.campaign_dir}"
        " --points {input.points} --out {output.aggregate} > {log} 2>&1"


rule mc_report:
    input:
        aggregate=layout.study("{study}", "aggregate.json"),
    output:
        html=report(
            layout.study_page("{study}"),
            caption=os.path.join(REPORT_DIR, "study.rst"),
            category="Studies",
            labels={"study": "{study}"},
        ),
    log:
        layout.study("{study}", "logs", "report.log"),
    benchmark:
        layout.study("{study}", "benchmarks", "report.tsv")
    group:
        "study"
    conda:
        CONDA_ENV
    resources:
        mem_mb=300,
        runtime=1,
    params:
        study=lambda w: STUDY[w.study]["file"],
        campaign_dir=CAMPAIGN_DIR,
        digest=lambda w: mc.study_digest(STUDY[w.study]),
    shell:
        "calflow mc-report --study {params.study} --campaign-dir {params.campaign_dir}"
        " --aggregate {input.aggregate} --out {output.html} > {log} 2>&1"
