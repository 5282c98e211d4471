"""Digests of calflow's own code, so the workflow reruns what a code change affects.

Snakemake does not track code inside an installed package; each rule carries in its
``params`` the digest of the modules its step runs, so a change to those modules (or a
new calflow version) reruns exactly the jobs that use them.
"""

from __future__ import annotations

import hashlib
import importlib.util
from functools import lru_cache
from pathlib import Path

from calflow import __version__

# The modules each kind of step runs (packages include their submodules).
STEPS = {
    "acquire": ("calflow.acquisition", "calflow.checkpoint", "calflow.streams", "calflow.rigs", "calflow.plans",
                "calflow.controllers", "calflow.data", "calflow.commands", "calflow.kinematics", "calflow.lookup",
                "calflow.models", "calflow.gcs", "calflow.config"),
    "characterise": ("calflow.characterisation", "calflow.data", "calflow.commands", "calflow.config"),
    "identify": ("calflow.identification", "calflow.models", "calflow.kinematics", "calflow.lookup",
                 "calflow.stepwise", "calflow.data", "calflow.commands", "calflow.config"),
    "metrics": ("calflow.metrics", "calflow.evaluation", "calflow.evaluation_nano", "calflow.characterisation",
                "calflow.kinematics", "calflow.data", "calflow.commands", "calflow.config"),
    "summarise": ("calflow.summary", "calflow.summary_nano", "calflow.reference", "calflow.uncertainty",
                  "calflow.models", "calflow.evaluation_nano", "calflow.metrics", "calflow.data", "calflow.config"),
    "report": ("calflow.report", "calflow.summary", "calflow.config"),
}


def _files(module: str) -> list[Path]:
    spec = importlib.util.find_spec(module)
    if spec is None or spec.origin is None:
        raise ValueError(f"provenance: no module {module!r}")
    origin = Path(spec.origin)
    if origin.name == "__init__.py":
        root = origin.parent
        return sorted(p for p in root.rglob("*") if p.suffix in (".py", ".j2", ".css", ".yaml") and p.is_file())
    return [origin]


@lru_cache(maxsize=None)
def code_digest(step: str) -> str:
    """SHA-256 over calflow's version and the source of the modules of ``step``."""
    h = hashlib.sha256(__version__.encode())
    for module in STEPS[step]:
        for path in _files(module):
            h.update(path.name.encode())
            h.update(path.read_bytes())
    return h.hexdigest()
