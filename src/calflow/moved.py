"""Import paths that moved: they keep working for a release, with a DeprecationWarning.

When a module moves to the room its concept belongs to, a user's script that imports it
by the old path must not break the day they upgrade. Each old path in :data:`MOVED` is
served by a stand-in module: any name read from it (``from calflow.stepwise import
stepwisefit``, ``calflow.uncertainty.interferometer_budget``) comes from the new module,
with a :class:`DeprecationWarning` that names the new path. docs/api.md lists the public
names and the paths kept this way; the old paths go in the first release after 0.2.

This is the pattern SciPy uses for its private-module deprecations (a module-level
``__getattr__`` that warns, PEP 562), served by one import finder instead of a file per
old path, so the package's folders hold only the modules that are there.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import warnings

#: old module path → the module that holds its names now
MOVED: dict[str, str] = {
    "calflow.campaign": "calflow.configuration.campaign",
    "calflow.config": "calflow.configuration.config",
    "calflow.layout": "calflow.configuration.layout",
    "calflow.workflow_config": "calflow.configuration.workflow_config",
    "calflow.yamlfile": "calflow.configuration.yamlfile",
    "calflow.conformity": "calflow.certificate.conformity",
    "calflow.reference": "calflow.configuration.reference",
    "calflow.stepwise": "calflow.identification.stepwise",
    "calflow.uncertainty": "calflow.instruments.interferometer",
    "calflow.gcs.axis": "calflow.gcs.emulation.axis",
    "calflow.gcs.campaign_server": "calflow.gcs.emulation.campaign_server",
    "calflow.gcs.controller": "calflow.gcs.emulation.controller",
    "calflow.gcs.datarecorder": "calflow.gcs.emulation.datarecorder",
    "calflow.gcs.emulator": "calflow.gcs.emulation.emulator",
    "calflow.gcs.piezo": "calflow.gcs.emulation.piezo",
    "calflow.gcs.client": "calflow.gcs.wire.client",
    "calflow.gcs.link": "calflow.gcs.wire.link",
    "calflow.gcs.protocol": "calflow.gcs.wire.protocol",
    "calflow.gcs.transport": "calflow.gcs.wire.transport",
    "calflow.lifecycle.as_found": "calflow.lifecycle.decisions.as_found",
    "calflow.lifecycle.change": "calflow.lifecycle.decisions.change",
    "calflow.lifecycle.charts": "calflow.lifecycle.decisions.charts",
    "calflow.lifecycle.due": "calflow.lifecycle.decisions.due",
    "calflow.lifecycle.interval": "calflow.lifecycle.decisions.interval",
    "calflow.lifecycle.sprt": "calflow.lifecycle.decisions.sprt",
    "calflow.rigs.simulated.bundle": "calflow.data.bundle",
    "calflow.rigs.simulated.emulator": "calflow.gcs.emulation.campaign_emulator",
}


def _public(module) -> list[str]:
    names = getattr(module, "__all__", None)
    return list(names) if names is not None else [n for n in vars(module) if not n.startswith("_")]


class _MovedModules(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds the old paths of :data:`MOVED` (after every other finder) and serves stand-ins."""

    def find_spec(self, fullname, path=None, target=None):
        if fullname not in MOVED:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        return None  # a plain module

    def exec_module(self, module) -> None:
        old, new = module.__name__, MOVED[module.__name__]
        module.__doc__ = f"Moved to {new}; this path is kept for a release (docs/api.md)."

        def __getattr__(name: str):
            target = importlib.import_module(new)
            if name == "__all__":
                return _public(target)
            if name.startswith("__") and name.endswith("__"):
                raise AttributeError(f"module {old!r} has no attribute {name!r}")
            value = getattr(target, name)  # AttributeError as the new module gives it
            warnings.warn(
                f"{old} moved to {new}: import {name} from {new} ({old} goes in a later release)",
                DeprecationWarning,
                stacklevel=2,
            )
            return value

        def __dir__():
            return sorted(_public(importlib.import_module(new)))

        module.__getattr__ = __getattr__
        module.__dir__ = __dir__


def install() -> None:
    """Serve the old paths (once per process; called by ``import calflow``)."""
    if not any(isinstance(f, _MovedModules) for f in sys.meta_path):
        sys.meta_path.append(_MovedModules())
