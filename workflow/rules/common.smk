# Helpers shared by the rules: config validation, campaign look-up, rerun digests, and
# the list of files each campaign produces (asked of the campaign's family).
import os
import re
import shlex
import sys

from calflow import __version__ as CALFLOW_VERSION
from calflow.configuration import layout
from calflow.configuration.campaign import load as load_campaign
from calflow.configuration.config import check_campaign_name, digest
from calflow.provenance import code_digest
from calflow.errors import CalflowError
from calflow.family import all_rules_files, families
from calflow.family_workflow import frame_files, frame_recordings, hooks, load_study
from calflow.lifecycle.settings import check_stage_settings
from calflow.lifecycle.members import histories_on_disk, on_disk
from calflow.lifecycle.stages import check_needs, stages_of
from calflow.step import ALL
from calflow.steps import step as lookup_step
from calflow.configuration.workflow_config import load as load_checked_config
from calflow.certificate.annotate import check_stages


def selected_studies(config):
    """The studies to run: those of the configuration, unless the command line chose the
    campaigns (``--config 'campaigns=[...]'``) without naming studies too — running one's
    own campaign runs no Monte-Carlo study unless asked for."""
    overrides = workflow.config_settings.overwrite_config or {}
    if "campaigns" in overrides and "studies" not in overrides:
        return []
    return config["studies"]


try:
    # the configuration files read again by calflow's loader, --config values typed (Snakemake
    # passes nested ones as text), then validated
    config.update(
        load_checked_config(
            config,
            [*workflow.configfiles, *(workflow.overwrite_configfiles or ())],
            workflow.config_settings.overwrite_config,
        )
    )
    CAMPAIGN_DIR = config["campaign_dir"]
    CAMPAIGNS = [check_campaign_name(name) for name in config["campaigns"]]
    RIG_PLUGINS = config["rig_plugins"]
    CAMPAIGN = {
        name: load_campaign(f"{CAMPAIGN_DIR}/{name}.yaml", RIG_PLUGINS)
        for name in CAMPAIGNS
    }
    # the campaigns of a stage whose results are on disk, whichever run made them: a history
    # holds them all, and a campaign that reads another's results reads them there
    ON_DISK = on_disk(layout.results(), CAMPAIGN_DIR, tuple(CAMPAIGNS))
    STAGES = stages_of(CAMPAIGN, CAMPAIGN_DIR, ON_DISK)
    check_needs(CAMPAIGN, CAMPAIGN_DIR, lambda c: hooks(c).needs(c))
    # every stage's history is kept current, as the index is: the run's stages, and those
    # of the campaigns and histories on disk (rebuilt only when what they read changed)
    DISK_STAGES = histories_on_disk(layout.results(), ON_DISK)
    HISTORIES = sorted(set(STAGES) | set(DISK_STAGES))
    STAGE_SETTINGS_FILE = (
        "--config stages"
        if "stages" in (workflow.config_settings.overwrite_config or {})
        else (workflow.configfiles or ["config/config.yaml"])[-1]
    )
    check_stage_settings(config["stages"], CAMPAIGN, CAMPAIGN_DIR, STAGE_SETTINGS_FILE)
    # each stage's specification names figures its family computes, with a known rule
    check_stages(config["stages"], CAMPAIGN, STAGES, STAGE_SETTINGS_FILE)
    STUDIES = [check_campaign_name(name) for name in selected_studies(config)]
    STUDY = {
        name: load_study(f"{config['study_dir']}/{name}.yaml", CAMPAIGN_DIR)
        for name in STUDIES
    }
except CalflowError as exc:
    sys.stderr.write(f"calflow: error: {exc}\n")
    sys.exit(2)

# Rules call the `calflow` installed beside the Python that runs Snakemake, with the
# allow-list of rig plug-in modules (config `rig_plugins`, docs/rigs.md "Plugins are code").
# A job's output goes to its log; its stderr is kept as descriptor 3, where calflow also
# writes its one-line error, so a failed job's reason reaches the terminal.
shell.prefix(
    f"set -euo pipefail; export PATH={os.path.dirname(sys.executable)}:$PATH; "
    f"export CALFLOW_RIG_PLUGINS={shlex.quote(','.join(RIG_PLUGINS))}; "
    "exec 3>&2; export CALFLOW_ERROR_FD=3; "
)

# What the families add to the core rules: the open-loop runs the `acquire` rule serves,
# the runs the `metrics` rule serves, and their own rules files (included by the Snakefile).
OPEN_LOOP_RUNS = "|".join(
    dict.fromkeys(run for fam in families() for run in fam.hooks().open_loop_runs)
)
METRICS_RUNS = "|".join(
    runs for fam in families() if (runs := fam.hooks().metrics_runs) is not None
)
FAMILY_RULES = all_rules_files()
# Paths the families' rules files use (they live in the families' packages).
CONDA_ENV = os.path.join(workflow.basedir, "workflow", "envs", "calflow.yaml")
REPORT_DIR = os.path.join(workflow.basedir, "workflow", "report")


# A campaign's files are made only for the run's campaigns: another campaign's results (an
# interim check's reference run before, a stage's earlier campaigns) are read as they are
# on disk, never remade from a configuration this run does not have.
wildcard_constraints:
    campaign="|".join(re.escape(n) for n in CAMPAIGNS) or "(?!)",
    model="[A-Za-z0-9_]+",
    run=OPEN_LOOP_RUNS,


def campaign_file(wildcards):
    return f"{CAMPAIGN_DIR}/{wildcards.campaign}.yaml"


def reads(step, *keys):
    """The params of a job that runs ``calflow <step>`` on a campaign: ``sections``, handed to
    the job (``--sections {params.sections:q}``: it cannot read another,
    calflow.configuration.campaign.Campaign.only), and ``digest``, of the same sections and the
    step's code. Snakemake reruns a job when its params change, so the job reruns exactly when
    a section it reads, or the calflow code it runs, changes.

    The sections are those the step declares (calflow.step.Step.sections: the robot and the
    start, then its ``reads``), then ``keys``, what this rule's jobs read besides: one key of a
    section (``"validation.heldout"``: the job is handed that key only), a function of the
    wildcards giving a section's name (or None, or a list of names: a family's answer), or
    :data:`ALL`. Use as ``params: **reads("metrics", ...)``.
    """
    declared = lookup_step(step).sections()

    def _keys(w):
        names = list(declared)
        for key in keys:
            key = key(w) if callable(key) else key
            names += [key] if isinstance(key, str) else list(key or ())
        return list(dict.fromkeys(names))

    def _sections(w):
        return ",".join(_keys(w))

    def _digest(w):
        c = CAMPAIGN[w.campaign]
        values = [dict(c) if k == ALL else c.part(k) for k in _keys(w)]
        return digest([code_digest(step, c["robot"])] + values)

    return {"sections": _sections, "digest": _digest}


def hooks_of(name):
    """The FamilyWorkflow of campaign ``name``'s family: what the core rules ask it."""
    return hooks(CAMPAIGN[name])


def models_of(c):
    """The models campaign ``c`` identifies."""
    return hooks(c).models(c)


def results_of(name):
    """Every result file of campaign ``name`` that its summary and report draw on."""
    return hooks_of(name).results_of(CAMPAIGN[name])


def summary_truth(w):
    """The rig's truth the summary step reads (tests and reports only), or none."""
    return hooks_of(w.campaign).summary_truth(CAMPAIGN[w.campaign])


def budget_file(name):
    """The error budget's replays the summary reads, or none."""
    return hooks_of(name).budget_files(CAMPAIGN[name])


def plan_section(w):
    """The name of the campaign section that defines an open-loop run's plan (or the names of
    those its plan reads)."""
    return hooks_of(w.campaign).open_loop_runs.get(w.run)


def acquire_inputs(w):
    """Files an open-loop run's plan reads, by option of ``calflow acquire``; a run recorded
    as camera frames is served from its decoded run (rule decode_frames). Every input is
    read (no order-only ``ancient`` input: Snakemake then skips a job's own changed params
    when the job it waits on reruns, snakemake/snakemake#4166; order is a rule priority).
    """
    c = CAMPAIGN[w.campaign]
    inputs = dict(hooks_of(w.campaign).acquire_inputs(c, w.run))
    if w.run in frame_recordings(c):
        inputs["decoded"] = layout.decoded(w.campaign, w.run)
    return inputs


def frames_of(w):
    """The files a frame recording's decoding reads (rule decode_frames)."""
    c = CAMPAIGN[w.campaign]
    if w.run not in frame_recordings(c):
        raise ValueError(
            f"{w.campaign}: run {w.run!r} is not recorded as camera frames"
        )
    return frame_files(frame_recordings(c)[w.run])


def frames_digest(w):
    """What decoding a frame recording reads besides the campaign's sections (rule
    decode_frames hands and digests those): the table's and the pattern file's contents,
    the frame files' sizes and times (Snakemake does not rerun a job for a newer file no
    rule makes)."""
    files = frame_files(frame_recordings(CAMPAIGN[w.campaign])[w.run])
    stamps = [
        [f, os.stat(f).st_size, os.stat(f).st_mtime_ns]
        for f in files[:-2]
        if os.path.exists(f)
    ]
    contents = [_sha256(f) if os.path.exists(f) else None for f in files[-2:]]
    return digest([stamps, contents])


def _sha256(path):
    import hashlib

    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def identify_inputs(w):
    return hooks_of(w.campaign).identify_inputs(CAMPAIGN[w.campaign], w.model)


def input_args(w, input):
    """The named inputs as options: ``--name path``."""
    return " ".join(f"--{k} {v}" for k, v in input.items())


identify_args = input_args


def identify_sections(w):
    """The sections identification of a model reads (its family says)."""
    return hooks_of(w.campaign).identify_sections(CAMPAIGN[w.campaign], w.model)


def report_files(name):
    """What the report draws on besides the summary (its family says)."""
    return hooks_of(name).report_files(CAMPAIGN[name])


def rig_slots(wildcards):
    """One unit of the global `rig` resource when the campaign acquires from a real rig.

    A physical rig moves one plan at a time; simulators are independent per run.
    """
    return 0 if CAMPAIGN[wildcards.campaign]["rig"]["factory"] == "simulated" else 1


# ---------------------------------------------------------------- stage histories
def stage_members(stage):
    """The campaigns of ``stage``'s history, the run's and those on disk, by name: the same
    list whichever of them the run has (docs/lifecycle.md)."""
    disk = [n for n, d in ON_DISK.items() if d["stage"] == stage]
    return sorted(list(STAGES.get(stage, [])) + disk)


def stage_summaries(w):
    """Every member's summary: made by this run for its campaigns, else read as it is on disk
    (a newer one reruns the history)."""
    return [layout.summary(n) for n in stage_members(w.stage)]


def stage_robot(stage):
    """The robot of the stage's campaigns: the run's, else those on disk, else its history's."""
    names = STAGES.get(stage) or []
    if names:
        return CAMPAIGN[names[0]]["robot"]
    if stage not in DISK_STAGES:
        raise CalflowError(
            f"{layout.stage(stage)}: expected a stage with campaigns in the run or on disk"
        )
    return DISK_STAGES[stage]


def stage_settings(w):
    import json

    return json.dumps(config.get("stages", {}).get(w.stage, {}), sort_keys=True)


def certificate_settings(name):
    """The specification and decision rule of campaign ``name``'s stage (JSON), or {}."""
    import json

    stage = CAMPAIGN[name].get("stage")
    settings = config.get("stages", {}).get(stage, {}) if stage else {}
    keys = ("specification", "decision_rule")
    return json.dumps({k: settings[k] for k in keys if k in settings}, sort_keys=True)


def laboratory_settings():
    """The laboratory that issues the certificates (config ``laboratory``), JSON."""
    import json

    return json.dumps(config.get("laboratory") or {}, sort_keys=True)


def item_settings(name):
    """The item campaign ``name``'s certificate describes (config ``stages.<id>.item``), JSON."""
    import json

    stage = CAMPAIGN[name].get("stage")
    item = config.get("stages", {}).get(stage, {}).get("item", {}) if stage else {}
    return json.dumps(item, sort_keys=True)


def stage_digest(w):
    """What the history reads besides the summaries: which campaigns it holds (one appearing,
    going or moving to another stage reruns it) and what each campaign file says of them.
    """
    keys = ("stage", "robot", "start", "tolerance_um")
    members = [
        (
            {"campaign": n, **{k: CAMPAIGN[n].get(k) for k in keys}, "note": None}
            if n in CAMPAIGN
            else {"campaign": n, **ON_DISK[n]}
        )
        for n in stage_members(w.stage)
    ]
    return digest(
        [code_digest("history", stage_robot(w.stage)), stage_settings(w)] + members
    )
