"""Published results put beside calflow's in summaries and reports.

Each robot family names its own (:attr:`calflow.family.Family.reference`, per robot a dict
with a ``source``); the core reads them through the registry.
"""

from __future__ import annotations


def of(robot: str) -> dict:
    """The published values of ``robot``'s family for that robot (``{}`` when it has none)."""
    from calflow.family import family_of

    return family_of(robot).reference_of(robot)
