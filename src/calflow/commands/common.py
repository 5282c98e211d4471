"""Helpers shared by the subcommands: campaign loading, metadata, rigs."""

from __future__ import annotations

import shlex
import sys

from calflow import __version__
from calflow.configuration.campaign import Campaign, Sections
from calflow.configuration.campaign import load as load_campaign
from calflow.configuration.config import campaign_digest
from calflow.data.runs import RunMetadata


def campaign(path: str, rig_plugins=None) -> dict:
    """The campaign at ``path``; with ``rig_plugins`` (the allow-list of plug-in modules) its
    ``module:callable`` rig factory is checked too (docs/rigs.md, "Plugins are code")."""
    return load_campaign(path, rig_plugins)


def handed(c: Campaign, sections: str | None, step: str) -> Campaign | Sections:
    """Campaign ``c`` as a step sees it: only the ``sections`` its rule hands it (``--sections
    a,b,c``; :meth:`calflow.configuration.campaign.Campaign.only`), or all of it when None or
    when they include ``*`` (a step that reads the whole campaign: the summary, the report)."""
    keys = [s for s in (sections or "").split(",") if s]
    if sections is None or "*" in keys:
        return c
    return c.only(keys, step)


def campaign_of(args, rig_plugins=None) -> Campaign | Sections:
    """The campaign a subcommand's job reads: file ``args.campaign`` (:func:`campaign`), only
    the sections its rule hands it (``args.sections``, :func:`handed`; all when not given)."""
    step = f"calflow {getattr(args, 'command', None) or 'step'}"
    return handed(campaign(args.campaign, rig_plugins), getattr(args, "sections", None), step)


def _command(argv: list[str]) -> list[str]:
    """The command line a file's ``history`` records: without ``--sections``, which only limits
    what the step may read (a step that runs gives the same file with or without it)."""
    out, skip = [], False
    for arg in argv:
        if skip:
            skip = False
        elif arg == "--sections":
            skip = True
        elif not arg.startswith("--sections="):
            out.append(arg)
    return out


def meta(c: dict, source: str, plan: str, model: str | None = None) -> RunMetadata:
    return RunMetadata(
        campaign=c["name"],
        robot=c["robot"],
        source=source,
        plan=plan,
        # the stamp of the campaign the file comes from: all of it, whichever sections the step reads
        config_sha256=campaign_digest(c.campaign if isinstance(c, Sections) else c),
        start=c["start"],
        model=model,
        history=f"calflow {__version__}: {' '.join(shlex.quote(a) for a in _command(sys.argv[1:]))}",
    )


def open_rig(c: dict, run_id: str, start_s: float = 0.0, rig_plugins=None, decoded: str | None = None):
    """The campaign's rig for run ``run_id``; returns (rig, source).

    The campaign's ``rig.options``, overridden by ``rig.runs.<run_id>``, plus what the
    robot's family adds per run (:class:`calflow.family.Family` ``rig_options``: seeds and
    noise streams of simulated rigs). A replayed recording plays the stream of the run.
    ``rig_plugins``: the modules a ``module:callable`` factory may come from (default: the
    ``CALFLOW_RIG_PLUGINS`` environment variable). ``decoded``: the run file of a frame
    recording (``calflow decode-run``), served by the replay rig.
    """
    from calflow.family import family_of, resolve
    from calflow.rigs import load_rig

    rig_cfg = c["rig"]
    options = {**rig_cfg.get("options", {}), **rig_cfg.get("runs", {}).get(run_id, {})}
    if rig_cfg["factory"] == "replay":
        options["stream"] = run_id
        options["campaign_start"] = c["start"]  # an instrument's clock is served in campaign time
        if decoded:  # a frame recording, decoded by `calflow decode-run`
            options["decoded"] = decoded
    else:
        options = resolve(family_of(c["robot"]).rig_options)(c, rig_cfg["factory"], run_id, options, start_s)
    return load_rig(rig_cfg["factory"], c["robot"], options, rig_plugins)


def pairs(items: list[str] | None, flag: str) -> dict[str, str]:
    """Parse NAME=PATH arguments."""
    from calflow.errors import CalflowError

    out = {}
    for item in items or []:
        name, sep, path = item.partition("=")
        if not sep:
            raise CalflowError(f"calflow: {flag}: expected NAME=PATH, got {item!r}")
        out[name] = path
    return out
