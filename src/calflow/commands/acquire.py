"""``calflow acquire``: build a run's plan from the campaign, run it on the rig, write the run.

The plan is looked up by name in the campaign's robot family (:mod:`calflow.family`); the
builder returns the plan with the run's name, the model commanding it and, for runs with
run-time compensation, the controller.
"""

from __future__ import annotations

from calflow.configuration.handed import campaign_of
from calflow.data.runs import meta
from calflow.errors import RigError
from calflow.family import family_of
from calflow.rigs.campaign_rig import open_rig


def _recorded(job, rig, c: dict):
    """The acquisition of a replayed instrument recording: its own plan, no controller."""
    from calflow.instruments.pattern.hpcode.scale import RECORD_KEYS
    from calflow.plan import Acquisition

    robot = rig.attrs.get("robot")
    if robot != c["robot"] or job.controller is not None:
        rig.close()
        why = (
            f"holds a {robot} recording, the campaign's robot is {c['robot']!r}"
            if robot != c["robot"]
            else "is an instrument's recording, which cannot replay a run commanded through the models at run time"
        )
        raise RigError(f"{rig.path}: rig.options.recordings.{job.run_id}: {why}")
    return Acquisition(
        rig.recorded_plan,
        job.run_id,
        job.model,
        None,
        {
            **job.attrs,
            "imported_from": rig.attrs.get("imported_from", rig.path.name),
            # a decoded frame recording's pooled pixel size and its trend test, when it has one
            **{k: v for k, v in rig.attrs.items() if k in RECORD_KEYS},
        },
    )


def acquire_job(c: dict, plan_name: str, args, plugins=None, journal_path: str | None = None):
    """The run of plan ``plan_name`` of campaign ``c`` on the campaign's rig, as ``calflow
    acquire`` makes it: the plan looked up in the family, a replayed instrument's own plan,
    the plan's runner, a progress bar on a terminal, a journal at ``journal_path`` when given.
    Returns (dataset, the rig's truth, the journal or None, the closed rig)."""
    from calflow.acquisition.checkpoint import Journal, plan_digest
    from calflow.acquisition.progress import progress
    from calflow.acquisition.runner import acquire

    job = family_of(c["robot"]).plan(c["robot"], plan_name)(c, args)
    rig, source = open_rig(c, job.run_id, job.plan.start_s, plugins, getattr(args, "decoded", None))
    if getattr(rig, "recorded_plan", None) is not None:  # an instrument's file: replay the poses it chose
        job = _recorded(job, rig, c)
    journal = Journal(journal_path, plan_digest(job.plan)) if journal_path else None
    try:
        with progress(f"{c['name']} {job.run_id}", len(job.plan)) as step:
            ds = (job.runner or acquire)(
                job.plan, rig, meta(c, source, plan_name, job.model), journal, step, job.controller
            )
        truth = rig.truth() if hasattr(rig, "truth") else {"available": False}
    finally:
        rig.close()
    ds.attrs.update(job.attrs)
    return ds, truth, journal, rig


def run(args) -> None:
    from calflow.configuration.rig_factory import allowed_modules
    from calflow.data.io import output_folder, write_dataset, write_json

    plugins = allowed_modules(getattr(args, "rig_plugins", None))
    c = campaign_of(args, plugins)
    for out in filter(None, (args.out, args.truth)):  # before the rig moves: a bad --out costs no run
        output_folder(out)
    ds, truth, journal, rig = acquire_job(c, args.plan, args, plugins, f"{args.out}.journal")
    empty = [n for n in rig.sensors if n in ds and ds.sizes.get("sample") and ds[n].isnull().all()]
    if empty:  # refused here, not two rules later as "needs at least 2 valid poses"
        journal.close(remove=True)
        raise RigError(
            f"{args.out}: rig {c['rig']['factory']!r}: every reading of {empty[0]} in plan "
            f"{args.plan!r} is NaN; no run written (is the sensor connected and in range?)"
        )
    if args.truth:
        write_json(truth, args.truth)
    write_dataset(ds, args.out)
    journal.close(remove=True)
