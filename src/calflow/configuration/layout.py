"""Where the workflow's files live: the layout of ``results/`` and ``reports/``, written once.

Each function returns a path as a POSIX string relative to the workflow's folder, exactly
as the rules name it (the rules, the core's and the families', call these functions: no
``results/`` or ``reports/`` path is spelled anywhere else) (README.md, "Outputs"): ``run("c", "identification")`` is
``results/c/runs/identification.nc``. A name is one path component (a campaign, run, model
or stage name, or a rule's wildcard such as ``"{campaign}"``): one with a ``/``, a ``\\``,
``..`` or a leading ``.`` is refused, so no name reaches outside ``results/`` or
``reports/``.
"""

from __future__ import annotations

RESULTS = "results"
REPORTS = "reports"


def _part(name: object, what: str) -> str:
    text = str(name)
    if not text or "/" in text or "\\" in text or ".." in text or text.startswith(".") or "\0" in text:
        raise ValueError(f"{what} {text!r}: expected one path component (no '/', '\\', '..' or leading '.')")
    return text


def results(*parts: str) -> str:
    """The results folder, or a path inside it that belongs to no campaign, stage or study
    (the index's log): ``results[/<parts>...]``."""
    return "/".join([RESULTS, *(_part(p, "path component") for p in parts)])


def reports(*parts: str) -> str:
    """The reports folder, or a path inside it: ``reports[/<parts>...]``."""
    return "/".join([REPORTS, *(_part(p, "path component") for p in parts)])


def campaign(name: str, *parts: str) -> str:
    """A campaign's results folder, or a path inside it: ``results/<name>[/<parts>...]``."""
    return "/".join([RESULTS, _part(name, "campaign"), *(_part(p, "path component") for p in parts)])


def run(name: str, run_id: str) -> str:
    """A run dataset: ``results/<campaign>/runs/<run_id>.nc``."""
    return campaign(name, "runs", f"{_part(run_id, 'run')}.nc")


def truth(name: str, run_id: str) -> str:
    """A simulated rig's truth of a run (tests and reports only): ``results/<campaign>/truth/<run_id>.json``."""
    return campaign(name, "truth", f"{_part(run_id, 'run')}.json")


def model(name: str, model_name: str) -> str:
    """An identified model: ``results/<campaign>/models/<model>.nc``."""
    return campaign(name, "models", f"{_part(model_name, 'model')}.nc")


def metrics(name: str, kind: str) -> str:
    """Metrics of a run or a study: ``results/<campaign>/metrics/<kind>.nc``."""
    return campaign(name, "metrics", f"{_part(kind, 'metrics')}.nc")


def luts(name: str, kind: str = "position") -> str:
    """Lookup tables: ``results/<campaign>/luts/<kind>.nc``."""
    return campaign(name, "luts", f"{_part(kind, 'lookup table')}.nc")


def summary(name: str) -> str:
    """The campaign's summary: ``results/<campaign>/summary.json``."""
    return campaign(name, "summary.json")


def logs(name: str) -> str:
    """The campaign's job logs: ``results/<campaign>/logs``."""
    return campaign(name, "logs")


def log(name: str, step: str) -> str:
    """A job's log: ``results/<campaign>/logs/<step>.log``."""
    return campaign(name, "logs", f"{_part(step, 'step')}.log")


def benchmark(name: str, step: str) -> str:
    """A job's benchmark (Snakemake's ``benchmark:``): ``results/<campaign>/benchmarks/<step>.tsv``."""
    return campaign(name, "benchmarks", f"{_part(step, 'step')}.tsv")


def decoded(name: str, run_id: str) -> str:
    """A frame recording decoded into a run: ``results/<campaign>/decoded/<run_id>.nc``."""
    return campaign(name, "decoded", f"{_part(run_id, 'run')}.nc")


def index() -> str:
    """The page of every campaign: ``reports/index.html``."""
    return reports("index.html")


def certificate(name: str, suffix: str = "html") -> str:
    """The campaign's certificate: ``reports/<campaign>/certificate.<html|pdf>``."""
    return reports(_part(name, "campaign"), f"certificate.{_part(suffix, 'suffix')}")


def stage(stage_id: str, *parts: str) -> str:
    """A stage's results folder, or a path inside it: ``results/stages/<stage>[/<parts>...]``."""
    return results("stages", _part(stage_id, "stage"), *parts)


def history(stage_id: str) -> str:
    """A stage's history: ``results/stages/<stage>/history.json``."""
    return stage(stage_id, "history.json")


def study(name: str, *parts: str) -> str:
    """A Monte-Carlo study's results folder, or a path inside it: ``results/studies/<study>[/<parts>...]``."""
    return results("studies", _part(name, "study"), *parts)


def report(name: str, suffix: str = "html") -> str:
    """The campaign's report: ``reports/<campaign>/report.<html|pdf>``."""
    return f"{REPORTS}/{_part(name, 'campaign')}/report.{_part(suffix, 'suffix')}"


def stage_history(stage: str, suffix: str = "html") -> str:
    """A stage's history report: ``reports/stages/<stage>/history.<html|pdf>``."""
    return f"{REPORTS}/stages/{_part(stage, 'stage')}/history.{_part(suffix, 'suffix')}"


def study_point(study: str, seeds: str, noise: str, poses: int | str) -> str:
    """One point of a Monte-Carlo study: ``results/studies/<study>/points/<seeds>_<noise>_<poses>.json``."""
    point = _part(f"{seeds}_{noise}_{poses}", "study point")
    return f"{RESULTS}/studies/{_part(study, 'study')}/points/{point}.json"


def study_page(study: str) -> str:
    """A Monte-Carlo study's page: ``reports/studies/<study>.html``."""
    return f"{REPORTS}/studies/{_part(study, 'study')}.html"
