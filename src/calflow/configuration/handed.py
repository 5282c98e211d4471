"""The campaign as a step sees it: the file its job names, only the sections its rule hands it
(the stamp every file the step writes carries is :func:`calflow.data.runs.meta`).

Every step that reads a campaign reads it through :func:`campaign_of`; the rule hands the job
``--campaign FILE --sections a,b.c`` and digests the same sections (``reads`` in
workflow/rules/common.smk), so reading a section the rule did not hand is an error naming it
(:meth:`calflow.configuration.campaign.Campaign.only`).
"""

from __future__ import annotations

from calflow.configuration.campaign import Campaign, Sections
from calflow.configuration.campaign import load as load_campaign


def campaign(path: str, rig_plugins=None) -> Campaign:
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
    step = f"calflow {getattr(args, 'step', None) or 'step'}"
    return handed(campaign(args.campaign, rig_plugins), getattr(args, "sections", None), step)
