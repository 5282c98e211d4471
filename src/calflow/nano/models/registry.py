"""The nanopositioning models of Chapter 5, and reading any of them back from its file.

* :class:`GeometricModel` — Eq. (5.1), :mod:`calflow.nano.models.geometric`;
* :class:`ThermalDriftModel`, :class:`SingleModel`, :class:`TwoDoFModel` — Eq. (5.2)–(5.5),
  (5.10), :mod:`calflow.nano.models.thermal`;
* :class:`AdaptiveKMZModel` — Eq. (5.6), (5.7), :mod:`calflow.nano.models.kmz`.
"""

from __future__ import annotations

import xarray as xr

from calflow.nano.models.geometric import GeometricModel
from calflow.nano.models.kmz import AdaptiveKMZModel, KMZReading
from calflow.nano.models.terms import ModelInputError, Term
from calflow.nano.models.thermal import SingleModel, ThermalDriftModel, TwoDoFModel

__all__ = [
    "AdaptiveKMZModel",
    "GeometricModel",
    "KMZReading",
    "ModelInputError",
    "SingleModel",
    "Term",
    "ThermalDriftModel",
    "TwoDoFModel",
    "model_from_dataset",
]


def model_from_dataset(ds: xr.Dataset):
    """Rebuild any nano model from its dataset, dispatching on ``ds.attrs["model"]``."""
    classes = {
        c.kind: c for c in (GeometricModel, TwoDoFModel, AdaptiveKMZModel, ThermalDriftModel, SingleModel)
    }
    kind = ds.attrs.get("model")
    if kind not in classes:
        raise ModelInputError(f"unknown nano model {kind!r}; expected one of {sorted(classes)}")
    return classes[kind].from_dataset(ds)
