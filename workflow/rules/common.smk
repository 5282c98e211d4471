# Helpers shared by the rules: config validation, campaign look-up, rerun digests, and
# the list of files each campaign produces.
import os
import shlex
import sys

from calflow import __version__ as CALFLOW_VERSION
from calflow.config import (
    check_campaign_name,
    digest,
    load_campaign,
    load_workflow_config,
)
from calflow.provenance import code_digest
from calflow.errors import ConfigError
from calflow.xytheta.studies.montecarlo import load_study


def selected_studies(config):
    """The studies to run: those of the configuration, unless the command line chose the
    campaigns (``--config 'campaigns=[...]'``) without naming studies too — running one's
    own campaign runs no Monte-Carlo study unless asked for."""
    overrides = workflow.config_settings.overwrite_config or {}
    if "campaigns" in overrides and "studies" not in overrides:
        return []
    return config["studies"]


try:
    config.update(load_workflow_config(config))
    CAMPAIGN_DIR = config["campaign_dir"]
    CAMPAIGNS = [check_campaign_name(name) for name in config["campaigns"]]
    RIG_PLUGINS = config["rig_plugins"]
    CAMPAIGN = {
        name: load_campaign(f"{CAMPAIGN_DIR}/{name}.yaml", RIG_PLUGINS)
        for name in CAMPAIGNS
    }
    STUDIES = [check_campaign_name(name) for name in selected_studies(config)]
    STUDY = {
        name: load_study(f"{config['study_dir']}/{name}.yaml", CAMPAIGN_DIR)
        for name in STUDIES
    }
except ConfigError as exc:
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

OPEN_LOOP_RUNS = (
    "identification|characterisation_x|characterisation_y|training|metrology"
)


wildcard_constraints:
    campaign="[A-Za-z0-9][A-Za-z0-9_-]*",
    model="[A-Za-z0-9_]+",
    run=OPEN_LOOP_RUNS,
    test="square|random_points",
    comp="none|linear|cubic",


def campaign_file(wildcards):
    return f"{CAMPAIGN_DIR}/{wildcards.campaign}.yaml"


def robot(wildcards):
    return CAMPAIGN[wildcards.campaign]["robot"]


def section(step, *keys):
    """A params function: digest of the code of ``step`` and the campaign sections it reads.

    Snakemake reruns a job when its params change, so each rule reruns exactly when a
    section it reads changes, or when the calflow code it runs changes.
    """

    def _digest(wildcards):
        c = CAMPAIGN[wildcards.campaign]
        return digest([code_digest(step, c["robot"])] + [c.get(k) for k in keys])

    return _digest


def rig_digest(run_id):
    """Digest of what a run's acquisition depends on: the rig, the campaign's clock, the code."""

    def _digest(wildcards):
        c = CAMPAIGN[wildcards.campaign]
        rid = run_id(wildcards) if callable(run_id) else run_id
        rig = {**c["rig"], "runs": c["rig"].get("runs", {}).get(rid)}
        return digest(
            [code_digest("acquire", c["robot"]), c["robot"], c["seed"], c["start"], rig]
        )

    return _digest


def reference_validation(w):
    """The validation section without its held-out part: what the reference runs read."""
    v = CAMPAIGN[w.campaign]["validation"]
    return {k: v[k] for k in v if k != "heldout"}


def xytheta_models(c):
    return list(c["models"])


def nano_models(c):
    return ["single", "adaptive_kmz"] if c["robot"] == "stage1d" else ["two_dof"]


def recorded_runs(c):
    """The run ids a replay campaign has recordings of (``rig.options.recordings`` as a
    mapping), or None when every run is acquired (or replayed from a whole runs/ folder).
    A recorded campaign analyses what its recordings hold; the summary says what is not
    supported (docs/data.md)."""
    recordings = c["rig"].get("options", {}).get("recordings")
    if c["rig"]["factory"] == "replay" and isinstance(recordings, dict):
        return set(recordings)
    return None


def results_of(name):
    """Every result file of campaign ``name`` that its summary and report draw on."""
    c = CAMPAIGN[name]
    base = f"results/{name}"
    if c["robot"] == "xytheta":
        models = xytheta_models(c)
        files = [f"{base}/models/{m}.nc" for m in models]
        files += [f"{base}/metrics/validation_{m}.nc" for m in models]
        files += [f"{base}/metrics/validation_heldout_{m}.nc" for m in models]
        files += [f"{base}/runs/validation_heldout_{m}.nc" for m in models]
        files.append(f"{base}/runs/identification.nc")
        files += [
            f"{base}/runs/angle_residuals_{s['base']}.nc"
            for s in c["models"].values()
            if "base" in s
        ]
        files.append(f"{base}/metrics/observability.nc")
        if "design_study" in c:  # opt-in (optimal design study)
            files.append(f"{base}/metrics/design_study.nc")
        tests = c["xy_tests"]["compensation"]
        if tests or any(spec.get("position_table") for spec in c["models"].values()):
            files.append(f"{base}/luts/position.nc")
            files += [f"{base}/runs/characterisation_{a}.nc" for a in "xy"]  # ISO 230-2
        files += [
            f"{base}/metrics/{t}_{k}.nc"
            for t in ("square", "random_points")
            for k in tests
        ]
        return files + export_results(name)
    recorded = recorded_runs(c)
    has = lambda run: recorded is None or run in recorded
    files = []
    if has("training"):
        files += [f"{base}/models/{m}.nc" for m in nano_models(c)]
        files += [f"{base}/metrics/training.nc", f"{base}/runs/training.nc"]
    if has("validation"):
        files.append(f"{base}/metrics/validation.nc")
        files.append(
            f"{base}/runs/validation.nc"
        )  # ISO 9283 vAP, AD/RD, drift; the error budget replays it
    if c["robot"] == "stage1d" and has("metrology"):
        files.append(f"{base}/metrics/metrology.nc")
        if not has(
            "training"
        ):  # the ISO 230-2 figures then come from the metrology run
            files.append(f"{base}/runs/metrology.nc")
    if c["step_response"]["enabled"] and has(
        "step_response"
    ):  # ISO 9283 stabilisation time, overshoot
        files.append(f"{base}/runs/step_response.nc")
    return files


def summary_truth(w):
    """The rig's truth the summary step reads (tests and reports only): the identification's
    for XYΘ, the validation's for the nano stages when the campaign has a validation run.
    """
    c = CAMPAIGN[w.campaign]
    if c["robot"] == "xytheta":
        return f"results/{w.campaign}/truth/identification.json"
    recorded = recorded_runs(c)
    if recorded is not None and "validation" not in recorded:
        return []
    return f"results/{w.campaign}/truth/validation.json"


def budget_file(name):
    """The error budget's replays (simulated XYΘ rigs with ``validation.heldout.error_budget``)."""
    c = CAMPAIGN[name]
    if c["robot"] != "xytheta" or c["rig"]["factory"] != "simulated":
        return []
    if not c["validation"]["heldout"]["error_budget"]:
        return []
    return [f"results/{name}/truth/error_budget.json"]


def budget_digest(w):
    """What the budget's replays read: the rig, the calibration's sections, the held-out targets."""
    c = CAMPAIGN[w.campaign]
    keys = (
        "seed",
        "start",
        "rig",
        "characterisation",
        "identification",
        "angle_residuals",
        "models",
    )
    v = c["validation"]
    return digest(
        [code_digest("error_budget", "xytheta")]
        + [c.get(k) for k in keys]
        + [v["heldout"], v["dwell_s"]]
    )


def plan_section(run):
    """The campaign section that defines an open-loop run's plan."""
    return {
        "identification": "identification",
        "characterisation_x": "characterisation",
        "characterisation_y": "characterisation",
        "training": "training",
        "metrology": "metrology",
    }[run]


def acquire_inputs(w):
    """The XY tables a designed identification plan reads for its discrepancy kernel."""
    c = CAMPAIGN[w.campaign]
    if w.run != "identification" or c["robot"] != "xytheta":
        return {}
    d = c["identification"].get("design") or {}
    given = d.get("discrepancy") or {}
    if (
        c["identification"].get("plan") != "optimal"
        or d.get("criterion") != "discrepancy"
    ):
        return {}
    if given.get("amplitude_um") is not None and given.get("length") is not None:
        return {}
    return {"luts": f"results/{w.campaign}/luts/position.nc"}


def identify_inputs(w):
    c = CAMPAIGN[w.campaign]
    base = f"results/{w.campaign}"
    if c["robot"] != "xytheta":
        return {"run": f"{base}/runs/training.nc"}
    spec = c["models"][w.model]
    if "base" in spec:
        return {
            "base": f"{base}/models/{spec['base']}.nc",
            "residuals": f"{base}/runs/angle_residuals_{spec['base']}.nc",
            "run": f"{base}/runs/identification.nc",
        }
    inputs = {"run": f"{base}/runs/identification.nc"}
    if spec.get("position_table"):
        inputs["luts"] = f"{base}/luts/position.nc"
    return inputs


def identify_args(w, input):
    return " ".join(f"--{k} {v}" for k, v in input.items())


def identify_digest(w):
    c = CAMPAIGN[w.campaign]
    if c["robot"] != "xytheta":
        return digest([code_digest("identify", c["robot"]), c["model"]])
    spec = c["models"][w.model]
    sections = [c["identification"], spec]
    if "base" in spec:
        sections.append(c["angle_residuals"])
    return digest([code_digest("identify", c["robot"]), c["seed"]] + sections)


def export_results(name):
    """The export metrics the summary draws on: every model of an XYΘ campaign; on a
    replayed rig, those whose export run was recorded (run id ``export_<model>``)."""
    c = CAMPAIGN[name]
    models = xytheta_models(c) if c["robot"] == "xytheta" else []
    if c["rig"]["factory"] == "replay":
        rec = c["rig"].get("options", {}).get("recordings", "")
        if isinstance(rec, dict):
            recorded = set(rec)
        elif os.path.isdir(rec):
            recorded = {f[: -len(".nc")] for f in os.listdir(rec) if f.endswith(".nc")}
        else:
            recorded = set()
        models = [m for m in models if f"export_{m}" in recorded]
    return [f"results/{name}/metrics/export_{m}.nc" for m in models]


def report_files(name):
    """What the report draws on: the summary's files and, for XYΘ, the identification poses."""
    files = results_of(name)
    if CAMPAIGN[name]["robot"] == "xytheta":
        files = files + [f"results/{name}/runs/identification.nc"]
    return files


def rig_slots(wildcards):
    """One unit of the global `rig` resource when the campaign acquires from a real rig.

    A physical rig moves one plan at a time; simulators are independent per run.
    """
    return 0 if CAMPAIGN[wildcards.campaign]["rig"]["factory"] == "simulated" else 1
