# calflow: calibration campaigns of micro- and nano-robotic positioning systems.
# Config is validated against workflow/schemas before any rule runs.


configfile: "config/config.yaml"


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"
include: "workflow/rules/acquire.smk"
include: "workflow/rules/identify.smk"
include: "workflow/rules/heldout.smk"
include: "workflow/rules/metrics.smk"
include: "workflow/rules/report.smk"
include: "workflow/rules/stages.smk"
include: "workflow/rules/certificate.smk"
include: "workflow/rules/cluster.smk"


# Each installed robot family's own rules (calflow.family.Family.rules).
for _rules in FAMILY_RULES:

    include: _rules


rule all:
    input:
        "reports/index.html",
        expand("reports/{campaign}/report.html", campaign=CAMPAIGNS),
        expand("reports/{campaign}/report.pdf", campaign=CAMPAIGNS),
        expand("reports/{campaign}/certificate.html", campaign=CAMPAIGNS),
        expand("reports/{campaign}/certificate.pdf", campaign=CAMPAIGNS),
        expand("reports/studies/{study}.html", study=STUDIES),
        expand("reports/stages/{stage}/history.html", stage=HISTORIES),
        expand("reports/stages/{stage}/history.pdf", stage=HISTORIES),
