"""What the core Snakemake rules ask a robot family about one campaign.

The core rules (``acquire``, ``identify``, ``metrics``, ``summarise``, ``report``, ``index``
in ``workflow/rules``) are the same for every robot; what differs — which runs the generic
``acquire`` rule serves, which models a campaign identifies and from which files, which
result files its summary and report draw on — each family answers with one
:class:`FamilyWorkflow`, named by its :class:`calflow.family.Family` (field ``workflow``).
A family's own steps (an XY characterisation, an export, a step response) are rules in the
family's own rules files (field ``rules``), included by the Snakefile.

Every method takes the loaded campaign ``c`` (with its ``name``); paths are relative to
the project folder, where Snakemake runs. Nothing here imports a numerical library: the
Snakefile reads it at every start.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

from calflow.errors import ConfigError


class FamilyWorkflow:
    """A family's answers to the core rules; the defaults describe a family with no runs."""

    #: open-loop run id → the campaign section that defines its plan (or the sections its plan
    #: reads, a tuple): the core ``acquire`` rule serves ``results/<campaign>/runs/<run>.nc``
    #: for these run ids, its job handed these sections and what every acquisition reads.
    open_loop_runs: Mapping[str, str | tuple[str, ...]] = {}
    #: regular expression of the run names (``runs/<name>.nc``) whose metrics the core
    #: ``metrics`` rule computes (``calflow metrics``); ``None`` for none.
    metrics_runs: str | None = None

    def models(self, c: dict) -> list[str]:
        """Names of the models the campaign identifies (``results/<c>/models/<name>.nc``)."""
        return []

    def results_of(self, c: dict) -> list[str]:
        """Every result file the campaign's summary draws on (``calflow summarise --files``)."""
        return []

    def summary_truth(self, c: dict) -> str | list[str]:
        """The rig's truth file the summary reads (tests and reports only), or ``[]``."""
        return []

    def budget_files(self, c: dict) -> list[str]:
        """The error budget's replay file the summary reads (``--budget``), or ``[]``."""
        return []

    def report_files(self, c: dict) -> list[str]:
        """What the report draws on besides the summary: by default the summary's files."""
        return self.results_of(c)

    def acquire_inputs(self, c: dict, run: str) -> dict[str, str]:
        """Files the core ``acquire`` rule reads for open-loop run ``run`` (by option name)."""
        return {}

    def identify_inputs(self, c: dict, model: str) -> dict[str, str]:
        """Files ``calflow identify`` reads for ``model``, by option name (``run``, ``luts`` …)."""
        return {}

    def identify_sections(self, c: dict, model: str) -> list[str]:
        """The names of the campaign sections identification of ``model`` reads: its job is
        handed those (and ``robot``) and a change to one reruns it."""
        return []

    def needs(self, c: dict) -> list[tuple[str, str, list[str]]]:
        """Another campaign's results the campaign reads: ``(key, campaign, files)`` per key of
        the campaign file that names another campaign (an interim check's reference). When the
        other campaign is not in the run its files must be on disk: the run reads them as they
        are and does not remake them (``calflow.lifecycle.stages.check_needs``)."""
        return []


DEFAULT = FamilyWorkflow()


def hooks(c: dict) -> FamilyWorkflow:
    """The :class:`FamilyWorkflow` of campaign ``c``'s family."""
    from calflow.family import family_of

    return family_of(c["robot"]).hooks()


def recorded_runs(c: dict) -> set[str] | None:
    """The run ids a replay campaign has recordings of (``rig.options.recordings`` as a
    mapping), or None when every run is acquired (or replayed from a whole runs/ folder).
    A recorded campaign analyses what its recordings hold; the summary says what is not
    supported (docs/data.md)."""
    recordings = c["rig"].get("options", {}).get("recordings")
    if c["rig"]["factory"] == "replay" and isinstance(recordings, dict):
        return set(recordings)
    return None


def replayed_runs(c: dict) -> set[str]:
    """The run ids a replay campaign can replay: its recordings' ids, or the ``.nc`` files of
    its recordings folder; empty when the folder does not exist."""
    rec = c["rig"].get("options", {}).get("recordings", "")
    if isinstance(rec, dict):
        return set(rec)
    if isinstance(rec, str) and rec and os.path.isdir(rec):
        return {f[: -len(".nc")] for f in os.listdir(rec) if f.endswith(".nc")}
    return set()


def frame_recordings(c: dict) -> dict[str, dict]:
    """The runs of a replay campaign recorded as camera frames (``format: frames``), by run
    id: each is decoded by the ``decode_frames`` rule before the replay rig serves it."""
    recordings = c["rig"].get("options", {}).get("recordings")
    if c["rig"]["factory"] != "replay" or not isinstance(recordings, dict):
        return {}
    return {
        run: spec
        for run, spec in recordings.items()
        if isinstance(spec, Mapping) and spec.get("format") == "frames"
    }


def frame_files(spec: Mapping) -> list[str]:
    """The files a frame recording's decoding reads: the stack or every image of the folder
    (the table names them), the table and the pattern file."""
    source = str(spec["file"])
    files = [source] if os.path.isfile(source) else []
    if os.path.isdir(source):
        suffixes = (".png", ".tif", ".tiff", ".bmp", ".pgm")
        files = sorted(os.path.join(source, f) for f in os.listdir(source) if f.lower().endswith(suffixes))
    return files + [str(spec["table"]), str(spec["pattern"])]


def load_study(path: str | Path, campaign_dir: str | Path = "config/campaigns") -> dict:
    """A study file (``config/studies/<name>.yaml``), loaded by the family of its base campaign
    (key ``campaign``) through the family's ``studies`` loader."""
    from calflow.configuration.campaign import raw
    from calflow.configuration.config import load_yaml
    from calflow.family import family_of, resolve

    path = Path(path)
    data = load_yaml(path)
    base = data.get("campaign") if isinstance(data, dict) else None
    if not isinstance(base, str):
        raise ConfigError(
            f"{path}: key 'campaign': expected the name of the study's base campaign, got {base!r}"
        )
    base_file = Path(campaign_dir) / f"{base}.yaml"
    if not base_file.is_file():
        raise ConfigError(f"{path}: key 'campaign': expected a campaign of {campaign_dir}, got {base!r}")
    campaign = raw(base_file)
    robot = campaign.get("robot") if isinstance(campaign, dict) else None
    family = family_of(str(robot), campaign.get("distribution") if isinstance(campaign, dict) else None)
    if family.studies is None:
        raise ConfigError(
            f"{path}: key 'campaign': the {family.name} family of robot {robot!r} has no studies"
        )
    return resolve(family.studies)(path, campaign_dir)
