"""Terms of the nanopositioning models and their stepwise identification (Sec. 5.2).

A model is a sum of :class:`Term` columns (powers of the position, Eq. (5.1); temperature
differences, Eq. (5.2)-(5.5)) whose coefficients :func:`identify` selects and fits with
:func:`calflow.identification.stepwise.stepwisefit`; the input checks every model shares.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calflow.errors import CalflowError
from calflow.identification.stepwise import stepwisefit


class ModelInputError(CalflowError, ValueError):
    """Bad numeric input to a nano model (NaN, shape, missing temperatures, ...)."""


@dataclass(frozen=True)
class Term:
    """One coefficient of a model: a row of the Table 5.1 analog.

    ``value`` is the coefficient the model uses (0.0 when stepwise left the term out);
    ``std_error`` and ``p_value`` are those ``stepwisefit`` reports (for an excluded term:
    the values it would get if added alone, MATLAB's convention); the intercept's standard
    error comes from the final least-squares fit and it has no p-value (NaN).
    """

    name: str
    unit: str
    long_name: str
    value: float
    std_error: float = float("nan")
    p_value: float = float("nan")
    in_model: bool = True


def power_unit(i: int) -> str:
    """Unit (UDUNITS) of the coefficient of x**i in a model q(x), q and x in um."""
    return {0: "um", 1: "1"}.get(i, f"um{1 - i}")


# ----------------------------------------------------------------------------- inputs
def as_vector(name: str, a, n: int | None = None) -> np.ndarray:
    """1-D float array (a scalar gives length 1); raise on NaN/inf or a wrong length."""
    arr = np.atleast_1d(np.asarray(a, dtype=float))
    if arr.ndim != 1:
        raise ModelInputError(f"{name} must be a scalar or 1-D array (um); got shape {arr.shape}")
    if n is not None and arr.size not in (1, n):
        raise ModelInputError(f"{name} has {arr.size} values; expected 1 or {n}")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise ModelInputError(
            f"{name} is not finite at index {bad[:5].tolist()} "
            f"(value {arr[bad[0]]}); NaN/inf cannot be commanded"
        )
    return arr


def as_temperatures(temps, n: int, k: int | None, who: str, *, allow_nan=False) -> np.ndarray:
    """Temperatures as (n, k) degC: (k,) is one reading broadcast to n rows."""
    if temps is None:
        raise ModelInputError(f"{who} needs temperatures (degC, shape (k,) or (n, k))")
    t = np.asarray(temps, dtype=float)
    if t.ndim == 1:
        t = np.broadcast_to(t, (n, t.size))
    if t.ndim != 2 or t.shape[0] not in (1, n) or (k is not None and t.shape[1] != k):
        raise ModelInputError(
            f"{who}: temperatures must have shape ({k or 'k'},) or ({n}, {k or 'k'}); got {np.shape(temps)}"
        )
    t = np.broadcast_to(t, (n, t.shape[1]))
    if not allow_nan and not np.isfinite(t).all():
        row = int(np.flatnonzero(~np.isfinite(t).all(axis=1))[0])
        raise ModelInputError(f"{who}: temperatures are not finite in row {row} ({t[row]})")
    return t


def identify(
    columns,
    specs,
    y,
    intercept: tuple[str, str, str],
    *,
    select="stepwise",
    penter=0.05,
    premove=0.10,
    force=(),
    scale=None,
    shift=None,
):
    """Fit ``y = intercept + sum_j c_j column_j`` by stepwise regression or least squares.

    columns: (n, p) regressors in raw units; specs: p tuples (name, unit, long_name);
    intercept: (name, unit, long_name). Internally column j is regressed as
    ``(column_j - shift_j) / scale_j`` (conditioning only: t-tests, hence the stepwise
    path, are invariant to it); coefficients are returned in raw units.
    Returns (terms, info) with the intercept as the last term.
    """
    X = np.asarray(columns, dtype=float)
    y = np.asarray(y, dtype=float)
    n, p = X.shape
    names = [s[0] for s in specs]
    unknown = set(force) - set(names)
    if unknown:
        raise ModelInputError(f"force names unknown terms {sorted(unknown)}; terms are {names}")
    if select not in ("stepwise", "all"):
        raise ModelInputError(f"select must be 'stepwise' or 'all'; got {select!r}")
    if np.isinf(X).any() or np.isinf(y).any():
        raise ModelInputError("training data contain inf; use NaN for missing samples")
    rows = np.isfinite(X).all(axis=1) & np.isfinite(y)
    if rows.sum() < p + 2:
        raise ModelInputError(
            f"only {int(rows.sum())} of {n} training rows are free of NaN; "
            f"{p} terms + intercept need at least {p + 2}"
        )
    shift = np.zeros(p) if shift is None else np.asarray(shift, dtype=float)
    scale = np.ones(p) if scale is None else np.asarray(scale, dtype=float)
    Xs = (X[rows] - shift) / scale
    forced = np.array([nm in force for nm in names])
    if select == "all":
        res = stepwisefit(Xs, y[rows], penter, premove, inmodel=np.ones(p, bool), keep=np.ones(p, bool))
    else:
        res = stepwisefit(Xs, y[rows], penter, premove, inmodel=forced, keep=forced)
    inm = np.asarray(res.inmodel)
    Z = np.column_stack([np.ones(Xs.shape[0]), Xs[:, inm]])
    cov = res.rmse**2 * np.linalg.pinv(Z.T @ Z)
    grad = np.concatenate([[1.0], -(shift / scale)[inm]])
    lam = res.intercept - float(np.sum((res.b * shift / scale)[inm]))
    terms = [
        Term(
            nm,
            unit,
            ln,
            float(res.b[j] / scale[j]) if inm[j] else 0.0,
            float(res.se[j] / scale[j]),
            float(res.pval[j]),
            bool(inm[j]),
        )
        for j, (nm, unit, ln) in enumerate(specs)
    ]
    terms.append(Term(*intercept, lam, float(np.sqrt(grad @ cov @ grad))))
    info = {
        "select": select,
        "penter": res.penter,
        "premove": res.premove,
        "rmse_um": float(res.rmse),
        "nobs": int(res.nobs),
        "n_dropped": int(n - res.nobs),
        "stepwise_history": "; ".join(r.message for r in res.history),
    }
    return tuple(terms), info


def geometric_specs(order: int, axis: str = "", letter: str = "a", var: str = "x"):
    """(name, unit, long_name) of the coefficients of var**i, i = 1..order."""
    where = f" in q_{axis}" if axis else ""
    return [
        (f"{letter}_{i}{axis}", power_unit(i), f"coefficient of {var}^{i}{where}")
        for i in range(1, order + 1)
    ]


def thermal_specs(k: int, letter: str = "b", axis: str = ""):
    """(name, unit, long_name) of the thermocouple coefficients, i = 1..k."""
    where = f" in q_{axis}" if axis else ""
    return [
        (f"{letter}_{i}{axis}", "um degC-1", f"thermal coefficient of t_{i}{where}") for i in range(1, k + 1)
    ]


def temperature_stats(t: np.ndarray, sensors, k: int) -> dict:
    """Keyword arguments (sensors, training_temperature) for a model trained on t (n, k)."""
    sensors = tuple(sensors) if sensors is not None else tuple(f"T{i + 1}" for i in range(k))
    if len(sensors) != k:
        raise ModelInputError(f"{len(sensors)} sensor names for {k} temperature channels")
    return {
        "sensors": sensors,
        "training_temperature": np.vstack([np.nanmin(t, 0), np.nanmean(t, 0), np.nanmax(t, 0)]),
    }


def _check_order(order) -> int:
    if isinstance(order, bool) or int(order) != order or not 1 <= order <= 9:
        raise ModelInputError(f"polynomial order must be an integer in 1..9; got {order!r}")
    return int(order)
