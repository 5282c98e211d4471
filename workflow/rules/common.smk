# Helpers shared by the rules: config validation, campaign look-up, rerun digests.
import os
import sys

from calflow import __version__ as CALFLOW_VERSION
from calflow.config import check_campaign_name, digest, load_campaign, load_workflow_config
from calflow.errors import ConfigError

# Rules call the `calflow` of the Python that runs Snakemake.
os.environ["PATH"] = os.path.dirname(sys.executable) + os.pathsep + os.environ.get("PATH", "")

try:
    config.update(load_workflow_config(config))
    CAMPAIGN_DIR = config["campaign_dir"]
    CAMPAIGNS = [check_campaign_name(name) for name in config["campaigns"]]
    CAMPAIGN = {name: load_campaign(f"{CAMPAIGN_DIR}/{name}.yaml") for name in CAMPAIGNS}
except ConfigError as exc:
    sys.stderr.write(f"calflow: error: {exc}\n")
    sys.exit(2)


wildcard_constraints:
    campaign="[A-Za-z0-9][A-Za-z0-9_-]*",
    model="[A-Za-z0-9_]+",


def campaign_file(wildcards):
    return f"{CAMPAIGN_DIR}/{wildcards.campaign}.yaml"


def section(*keys):
    """A params function: digest of the campaign sections a rule depends on.

    Snakemake reruns a job when its params change, so each rule reruns exactly when a
    section it reads changes, or when calflow itself changes version.
    """

    def _digest(wildcards):
        c = CAMPAIGN[wildcards.campaign]
        return digest([CALFLOW_VERSION] + [c.get(k) for k in keys])

    return _digest


def models_of(wildcards):
    return list(CAMPAIGN[wildcards.campaign]["models"])
