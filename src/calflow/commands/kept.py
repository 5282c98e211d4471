"""The U of an ISO 230-2 run kept between summaries (:func:`calflow.cache.cached_json`).

A characterisation's sweeps do not change when only a campaign's validation does, yet their
Monte Carlo is most of the summary's CPU. Its result is kept under a hash of everything it
depends on: the run's arrays (their bytes), its origin, the sensor's declared terms, the
Monte Carlo's trials and seed, numpy's and scipy's versions (the draws, the t and normal
quantiles) and the normalised source of every calflow module
:func:`calflow.metrics.uncertainty_iso.iso230_2_uncertainty` reaches (:mod:`calflow.provenance`). A result kept is therefore the one the same computation gives
now; a change of any of these computes it again. What is kept is every field of each
:class:`~calflow.metrics.uncertainty.Uncertainty` but its samples (which a summary does not
write), and a result computed now passes through the same JSON as one read back, so the
summary's bytes do not depend on whether the cache held it.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from calflow.metrics.uncertainty import Term, Uncertainty

#: the function whose result is kept ("module:function", the provenance's entry point form)
COMPUTES = "calflow.metrics.uncertainty_iso:iso230_2_uncertainty"
#: the fields of an :class:`~calflow.metrics.uncertainty.Uncertainty` kept (not its samples)
FIELDS = ("value", "U", "k", "u", "dof_eff", "interval", "budget", "method", "note", "monte_carlo")


def _plain(value):
    """A numpy scalar or array as the Python number or list JSON writes."""
    if hasattr(value, "tolist"):
        return value.tolist()
    raise TypeError(f"cannot keep a {type(value).__name__}")


def key(
    targets, forward, backward, terms: Sequence[Term], origin: float, trials: int | None, seed: int
) -> str:
    """SHA-256 of everything an ISO 230-2 run's U depends on (module notes)."""
    import numpy as np
    import scipy

    from calflow.provenance import closure, module_digest

    h = hashlib.sha256(f"iso230_2 U v1 numpy {np.__version__} scipy {scipy.__version__}".encode())
    h.update(module_digest(*closure(COMPUTES)).encode())
    for array in (targets, forward, backward):
        a = np.ascontiguousarray(np.asarray(array, float))
        h.update(repr(a.shape).encode())
        h.update(a.tobytes())
    fields = [[t.name, np.asarray(t.u, float).tolist(), t.scope, t.relative, t.dof] for t in terms]
    h.update(json.dumps([fields, float(origin), trials, seed]).encode())
    return h.hexdigest()


def iso230_2_uncertainty(
    targets,
    forward,
    backward,
    terms: Sequence[Term] = (),
    origin: float = 0.0,
    trials: int | None = None,
    seed: int = 0,
) -> dict[str, Uncertainty]:
    """:func:`calflow.metrics.uncertainty_iso.iso230_2_uncertainty` of the same arguments
    (``trials`` None: adaptive, its default), kept between processes (module notes); each
    result's ``samples`` is None."""
    from calflow.cache import cached_json
    from calflow.metrics import uncertainty_iso
    from calflow.metrics.uncertainty import Uncertainty

    def compute() -> dict:
        found = uncertainty_iso.iso230_2_uncertainty(
            targets, forward, backward, terms, origin=origin, trials=trials, seed=seed
        )
        records = {name: {f: getattr(u, f) for f in FIELDS} for name, u in found.items()}
        return json.loads(json.dumps(records, default=_plain))

    kept = cached_json("iso230_2", key(targets, forward, backward, terms, origin, trials, seed), compute)
    return {
        name: Uncertainty(**{**fields, "interval": tuple(fields["interval"])})
        for name, fields in kept.items()
    }
