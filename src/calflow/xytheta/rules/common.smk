# Helpers of the XYΘ family's own rules (what their jobs read).


def reference_validation(w):
    """The keys of the validation section the reference runs read: all the schema allows (an
    optional one the file leaves out is read as absent) but the held-out part."""
    from calflow.configuration.config import schema

    keys = schema("campaign-xytheta")["properties"]["validation"]["properties"]
    return [f"validation.{k}" for k in keys if k != "heldout"]


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
