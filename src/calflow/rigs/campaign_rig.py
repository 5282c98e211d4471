"""The rig of one run of a campaign: its factory, its options, what its family adds per run."""

from __future__ import annotations


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
    from calflow.rigs.plugin import load_rig

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
