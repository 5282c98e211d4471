"""Helpers shared by the subcommands: campaign loading, metadata, rigs.

Each lives in the layer it belongs to, where the layers below the commands can use it too
(docs/architecture.md): the campaign a step is handed in :mod:`calflow.configuration.handed`, the
metadata of the files it writes in :mod:`calflow.data.runs`, a run's rig in
:mod:`calflow.rigs.campaign_rig`.
They are named here as well, as the public core a family imports (docs/families.md).
"""

from __future__ import annotations

from calflow.configuration.handed import campaign, campaign_of, handed
from calflow.data.runs import meta
from calflow.rigs.campaign_rig import open_rig

__all__ = ["campaign", "campaign_of", "handed", "meta", "open_rig", "pairs"]


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
