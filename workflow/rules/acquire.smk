# Acquisition: a plan run on the campaign's rig becomes a run dataset.


rule acquire_identification:
    output:
        run="results/{campaign}/runs/identification.nc",
        truth="results/{campaign}/truth/identification.json",
    params:
        campaign=campaign_file,
        digest=section("robot", "seed", "start", "rig", "identification"),
    log:
        "results/{campaign}/logs/acquire_identification.log",
    resources:
        mem_mb=1000,
    shell:
        "calflow acquire --campaign {params.campaign} --plan identification"
        " --out {output.run} --truth {output.truth} > {log} 2>&1"
