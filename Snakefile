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
        layout.index(),
        expand(layout.report("{campaign}"), campaign=CAMPAIGNS),
        expand(layout.report("{campaign}", "pdf"), campaign=CAMPAIGNS),
        expand(layout.certificate("{campaign}"), campaign=CAMPAIGNS),
        expand(layout.certificate("{campaign}", "pdf"), campaign=CAMPAIGNS),
        expand(layout.study_page("{study}"), study=STUDIES),
        expand(layout.stage_history("{stage}"), stage=HISTORIES),
        expand(layout.stage_history("{stage}", "pdf"), stage=HISTORIES),
