# Helpers of the XYΘ family's own rules (what their params digest).


def reference_validation(w):
    """The validation section without its held-out part: what the reference runs read."""
    v = CAMPAIGN[w.campaign]["validation"]
    return {k: v[k] for k in v if k != "heldout"}


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
        [code_digest("error-budget", "xytheta")]
        + [c.get(k) for k in keys]
        + [v["heldout"], v["dwell_s"]]
    )


def interim_export(w):
    """The reference's export manifest: the bundle the stage runs (made by this run when the
    reference is in it, else read as it is on disk: the campaign wildcard is the run's).
    """
    from calflow.xytheta.plans.workflow import interim_export as export_of

    return export_of(CAMPAIGN[w.campaign])


def interim_reference_run(w):
    """The reference's closed-loop check of that bundle: the sequential test's H0."""
    from calflow.xytheta.plans.workflow import interim_reference_run as run_of

    return run_of(CAMPAIGN[w.campaign])


def as_found_export(w):
    """The export manifest of the calibration whose compensation the stage ran."""
    from calflow.xytheta.plans.workflow import as_found_export as manifest_of

    return manifest_of(CAMPAIGN[w.campaign])
