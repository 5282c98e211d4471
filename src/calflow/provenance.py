"""Digests of calflow's own code, so the workflow reruns what a code change affects.

Snakemake does not track code inside an installed package; each rule carries in its
``params`` the digest of the modules its step runs, so a change to those modules (or a
new calflow version) reruns exactly the jobs that use them.
"""

from __future__ import annotations

import hashlib
from functools import cache
from pathlib import Path

from calflow import __version__


def _files(module: str) -> list[Path]:
    """The source files of ``module``: a module, a package with its submodules and data, or
    a folder of templates inside the package (a family's ``report/templates``), of
    calflow or of a family's own installed package."""
    parts = module.split(".")
    if parts[0] == "calflow":
        root = Path(__file__).resolve().parent
    else:  # a family's own distribution: its top-level package, wherever it is installed
        import importlib.util

        spec = importlib.util.find_spec(parts[0])
        if spec is None or not spec.submodule_search_locations:
            raise ValueError(f"provenance: no installed package {parts[0]!r} (module {module!r})")
        root = Path(list(spec.submodule_search_locations)[0]).resolve()
    base = root.joinpath(*parts[1:])
    if base.with_suffix(".py").is_file():
        return [base.with_suffix(".py")]
    if base.is_dir():
        return sorted(
            p for p in base.rglob("*") if p.suffix in (".py", ".j2", ".css", ".yaml") and p.is_file()
        )
    raise ValueError(f"provenance: no module {module!r}")


@cache
def code_digest(step: str, robot: str) -> str:
    """SHA-256 over calflow's version and the source of the modules of ``step`` for
    campaigns of ``robot`` (the modules its family lists, :class:`calflow.family.Family`)."""
    from calflow.family import family_of

    modules = family_of(robot).modules.get(step)
    if modules is None:
        raise ValueError(f"provenance: the family of robot {robot!r} lists no modules for step {step!r}")
    return module_digest(*modules)


@cache
def module_digest(*modules: str) -> str:
    """SHA-256 over calflow's version and the source of ``modules`` (a step no family lists,
    such as the cross-campaign index: ``module_digest("calflow.report")``)."""
    h = hashlib.sha256(__version__.encode())
    for module in modules:
        for path in _files(module):
            h.update(path.name.encode())
            h.update(path.read_bytes())
    return h.hexdigest()
