"""Nanopositioning calibration models (thesis Chapter 5, Sec. 5.2 and 5.4.1).

All models are *inverse* models, as in the thesis: they give the joint command q (um) that
puts the stage at a measured position x (um), so commanding a target is one evaluation,
``q_c = model(x_T, t)``. Temperatures t are thermocouple readings in degC (shape (k,) for
one reading or (n, k)), times in s.

Where the models live:

* :class:`GeometricModel`, Eq. (5.1), and the models' shared machinery: this module; their
  terms and stepwise identification: :mod:`calflow.nano.models.terms`;
* ``ThermalDriftModel``, Eq. (5.2), ``SingleModel``, Eq. (5.3)-(5.5), and ``TwoDoFModel``,
  Eq. (5.10) (the models with thermal terms): :mod:`calflow.nano.models.thermal`;
* ``AdaptiveKMZModel`` and ``KMZReading``, Eq. (5.6)-(5.7): :mod:`calflow.nano.models.kmz`.

All of them can also be imported from :mod:`calflow.nano.models.registry`.

Common interface of the 1-DoF models: ``command(target, temperatures=None, reference=None)``,
``position(command, ...)`` (the model's forward map, solved by Newton),
``predict_error(target, ...)`` (the error the *uncalibrated* stage, commanded with
q = x_T, is predicted to make: position(x_T) - x_T, um), ``residuals(command, measured, ...)``
(training residual q - q_model, um), ``coefficients`` (a Table 5.1 analog),
``to_dataset()`` / ``from_dataset()``. Identification goes through
:func:`calflow.identification.stepwise.stepwisefit` (the thesis uses MATLAB's ``stepwisefit``); with
``select="all"`` it is plain least squares with every term kept in.

NaN policy: ``fit`` omits rows with a NaN anywhere (as MATLAB's ``stepwisefit`` does; the
count is kept as ``info["n_dropped"]``) and raises if too few rows remain; ``command``,
``position`` and ``predict_error`` raise :class:`ModelInputError` on any NaN or inf input.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
import xarray as xr

from calflow import __version__
from calflow.data.conventions import CF_CONVENTIONS
from calflow.nano.models.terms import (
    ModelInputError,
    Term,
    _check_order,
    as_temperatures,
    as_vector,
    geometric_specs,
    identify,
)

__all__ = ["GeometricModel"]


# ----------------------------------------------------------------------------- base
@dataclass(frozen=True, eq=False)
class _Model:
    """Coefficients + info, with the table and the netCDF round trip shared by all models."""

    terms: tuple[Term, ...]
    info: dict = field(default_factory=dict)
    sensors: tuple[str, ...] = ()
    training_temperature: np.ndarray | None = None  # (3, k): min, mean, max in degC
    kind = "nano"

    def value(self, name: str) -> float:
        for t in self.terms:
            if t.name == name:
                return t.value
        raise KeyError(f"{self.kind} model has no coefficient {name!r}")

    @property
    def coefficients(self) -> pd.DataFrame:
        """Table 5.1 analog: name, value, unit, std_error, p_value, in_model, long_name."""
        return pd.DataFrame(
            [
                {
                    "name": t.name,
                    "value": t.value,
                    "unit": t.unit,
                    "std_error": t.std_error,
                    "p_value": t.p_value,
                    "in_model": t.in_model,
                    "long_name": t.long_name,
                }
                for t in self.terms
            ]
        )

    def in_training_range(self, temperatures, margin: float = 0.0) -> np.ndarray:
        """True for each reading whose every channel lies in the training range +- margin."""
        if self.training_temperature is None:
            raise ModelInputError(f"{self.kind} model was trained without temperatures")
        t = np.atleast_2d(np.asarray(temperatures, dtype=float))
        lo, _, hi = self.training_temperature
        return np.all((t >= lo - margin) & (t <= hi + margin), axis=1)

    def _extra_attrs(self) -> dict:
        return {}

    def to_dataset(self, meta=None) -> xr.Dataset:
        """One scalar variable per coefficient (``units``, ``long_name``, ``std_error``,
        ``p_value``, ``in_model``); global attrs from ``meta`` (a RunMetadata) if given."""
        data = {
            t.name: xr.Variable(
                (),
                t.value,
                attrs={
                    "units": t.unit,
                    "long_name": t.long_name,
                    "std_error": t.std_error,
                    "p_value": t.p_value,
                    "in_model": int(t.in_model),
                },
            )
            for t in self.terms
        }
        coords = {}
        if self.training_temperature is not None:
            coords["sensor"] = xr.Variable(
                ("sensor",), np.array(self.sensors, dtype=object), attrs={"long_name": "thermocouple"}
            )
            for row, stat in enumerate(("min", "mean", "max")):
                data[f"training_temperature_{stat}"] = xr.Variable(
                    ("sensor",),
                    np.asarray(self.training_temperature[row], dtype=float),
                    attrs={"units": "degC", "long_name": f"{stat} temperature in training"},
                )
        attrs = (
            meta.attrs("model")
            if meta is not None
            else {"Conventions": CF_CONVENTIONS, "calflow_kind": "model", "calflow_version": __version__}
        )
        attrs.update({"model": self.kind, "terms": ",".join(t.name for t in self.terms)})
        attrs.update(
            {
                f"fit_{k}": v
                for k, v in self.info.items()
                if isinstance(v, (int, float, str)) and not isinstance(v, bool)
            }
        )
        attrs.update(self._extra_attrs())
        return xr.Dataset(data, coords=coords, attrs=attrs)

    @classmethod
    def _from_dataset_kwargs(cls, ds: xr.Dataset) -> dict:
        if ds.attrs.get("calflow_kind") != "model" or ds.attrs.get("model") != cls.kind:
            got = (ds.attrs.get("calflow_kind"), ds.attrs.get("model"))
            raise ModelInputError(
                f"dataset is not a {cls.kind!r} model (calflow_kind={got[0]!r}, model={got[1]!r})"
            )
        terms = tuple(
            Term(
                nm,
                ds[nm].attrs["units"],
                ds[nm].attrs["long_name"],
                float(ds[nm].values),
                float(ds[nm].attrs["std_error"]),
                float(ds[nm].attrs["p_value"]),
                bool(ds[nm].attrs["in_model"]),
            )
            for nm in ds.attrs["terms"].split(",")
        )
        info = {k[4:]: v for k, v in ds.attrs.items() if k.startswith("fit_")}
        info = {k: (v.item() if isinstance(v, np.generic) else v) for k, v in info.items()}
        kw = {"terms": terms, "info": info}
        if "sensor" in ds.coords:
            kw["sensors"] = tuple(str(s) for s in ds["sensor"].values)
            kw["training_temperature"] = np.vstack(
                [ds[f"training_temperature_{s}"].values for s in ("min", "mean", "max")]
            )
        return kw

    @classmethod
    def from_dataset(cls, ds: xr.Dataset):
        return cls(**cls._from_dataset_kwargs(ds))


@dataclass(frozen=True, eq=False)
class Nano1DModel(_Model):
    """A 1-DoF inverse model ``q = sum_i a_i x**i + offset(t) + lambda_KMZ``.

    Subclasses give the polynomial (:meth:`poly`, a_0..a_n1) and the x-independent part
    (:meth:`offset`, um, from temperatures), and may accept a ``reference`` (KMZ).
    """

    def poly(self) -> np.ndarray:
        raise NotImplementedError

    def offset(self, temperatures, n: int) -> np.ndarray:
        return np.zeros(n)

    def reference_offset(self, reference, n: int) -> np.ndarray:
        if reference is not None:
            raise ModelInputError(
                f"{self.kind} model takes no reference (KMZ); use calflow.nano.models.kmz.AdaptiveKMZModel"
            )
        return np.zeros(n)

    def _constant(self, temperatures, reference, n):
        return self.offset(temperatures, n) + self.reference_offset(reference, n)

    def command(self, target, temperatures=None, reference=None) -> np.ndarray:
        """Joint command q_c (um) for target positions x_T (um)."""
        x = as_vector("target", target)
        return np.polynomial.polynomial.polyval(x, self.poly()) + self._constant(
            temperatures, reference, x.size
        )

    def position(self, command, temperatures=None, reference=None) -> np.ndarray:
        """Forward map: the position x (um) where the model says command q lands (Newton)."""
        q = as_vector("command", command)
        a = self.poly()
        rhs = q - self._constant(temperatures, reference, q.size)
        pv, da = np.polynomial.polynomial.polyval, np.polynomial.polynomial.polyder(a)
        x = (rhs - a[0]) / a[1]
        for _ in range(60):
            step = (pv(x, a) - rhs) / pv(x, da)
            x = x - step
            if np.all(np.abs(step) <= 1e-11 * np.maximum(1.0, np.abs(x))):
                return x
        raise ModelInputError(
            f"{self.kind} model: forward map did not converge (is the "
            "polynomial monotonic over these commands?)"
        )

    def predict_error(self, target, temperatures=None, reference=None) -> np.ndarray:
        """Predicted error (um) of the uncalibrated stage commanded with q = x_T: x - x_T."""
        x_t = as_vector("target", target)
        return self.position(x_t, temperatures, reference) - x_t

    def residuals(self, command, measured, temperatures=None, reference=None) -> np.ndarray:
        """Fit residuals q - q_model(x_measured) in um (NaN rows give NaN)."""
        q, x = np.atleast_1d(np.asarray(command, float)), np.atleast_1d(np.asarray(measured, float))
        ok = np.isfinite(q) & np.isfinite(x)
        if temperatures is not None:
            t = as_temperatures(temperatures, q.size, None, "residuals", allow_nan=True)
            ok &= np.isfinite(t).all(axis=1)
            temperatures = t[ok]
        out = np.full(q.shape, np.nan)
        out[ok] = q[ok] - self.command(x[ok], temperatures, reference)
        return out


# ----------------------------------------------------------------------------- Eq. (5.1)
@dataclass(frozen=True, eq=False)
class GeometricModel(Nano1DModel):
    """Geometric inverse model, Eq. (5.1): ``q_g = sum_{i=0}^{n1} a_i x**i`` (n1 = 3).

    q_g is the joint command (um), x the position measured by the external sensor (um),
    a_i in um**(1-i). Fit on a constant-temperature (or de-drifted) data set.
    """

    kind = "geometric"

    @classmethod
    def fit(
        cls,
        command,
        measured,
        *,
        order: int = 3,
        select: str = "all",
        penter: float = 0.05,
        premove: float = 0.10,
        force=("a_1",),
    ) -> GeometricModel:
        """Least squares (``select="all"``) or stepwise fit of Eq. (5.1) to (q, x) pairs."""
        order = _check_order(order)
        q = np.asarray(command, dtype=float).ravel()
        x = np.asarray(measured, dtype=float).ravel()
        if q.shape != x.shape:
            raise ModelInputError(f"command and measured differ in length ({q.size} vs {x.size})")
        s = float(np.nanmax(np.abs(x))) or 1.0
        terms, info = identify(
            np.column_stack([x**i for i in range(1, order + 1)]),
            geometric_specs(order),
            q,
            ("a_0", "um", "coefficient of x^0"),
            select=select,
            penter=penter,
            premove=premove,
            force=force,
            scale=s ** np.arange(1, order + 1),
        )
        terms = (terms[-1],) + terms[:-1]  # a_0 first
        return cls(terms=terms, info={**info, "order": order})

    def poly(self) -> np.ndarray:
        return np.array([self.value(f"a_{i}") for i in range(self.info["order"] + 1)])

    def command_for(self, target) -> np.ndarray:
        """Eq. (5.1) evaluated at the target: q_g(x_T) in um."""
        return self.command(target)

    def offset(self, temperatures, n):
        return np.zeros(n)  # Eq. (5.1) has no thermal part; temperatures are ignored
