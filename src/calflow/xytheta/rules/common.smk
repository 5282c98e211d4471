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
    parts = (
        [code_digest("error_budget", "xytheta")]
        + [c.get(k) for k in keys]
        + [v["heldout"], v["dwell_s"]]
    )
    instrument = hooks(c).acquire_modules(c)  # the camera and decoder of an images rig
    return digest(parts + [module_digest(*instrument)] if instrument else parts)


def interim_export(w):
    """The reference's export manifest: the bundle the stage runs."""
    ref = CAMPAIGN[w.campaign]["interim_check"]["reference"]
    return f"results/{ref}/export/manifest.json"


def interim_reference_run(w):
    """The reference's closed-loop check of that bundle: the sequential test's H0."""
    check = CAMPAIGN[w.campaign]["interim_check"]
    return f"results/{check['reference']}/runs/export_{check['model']}.nc"
