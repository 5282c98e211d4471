"""Stepwise linear regression with the semantics of MATLAB's ``stepwisefit``.

The thesis (Chapter 5) identifies its thermal-drift models with MATLAB's
``stepwisefit`` (Statistics and Machine Learning Toolbox); this module re-implements
that procedure on numpy least squares so calflow can train the same models.
Reference: MathWorks, "stepwisefit -- Fit linear regression model using stepwise
regression", https://www.mathworks.com/help/stats/stepwisefit.html (the page's
"Algorithms" section and its Hald-cement example, reproduced in tests/identification/test_stepwise.py).

Algorithm (one move per step, as MATLAB documents it)
-----------------------------------------------------
The intercept is always in the model and is not a column of ``X``. Starting from the
initial model (``inmodel``, default: intercept only), repeat:

1. Fit the current model ``y ~ 1 + X[:, inmodel]`` by least squares.
2. For every *excluded* column j, compute the p-value it would have if it were added
   alone to the current model: the two-sided t-test of its coefficient in
   ``y ~ 1 + X[:, inmodel] + X[:, j]`` (the added-variable test; t**2 is the partial
   F statistic MATLAB's documentation speaks of). If the smallest such p-value is
   ``< penter``, add that column and go to 1.
3. Otherwise, for every *included* column, take the p-value of its t-test in the
   current model. If the largest is ``> premove``, remove that column and go to 1.
4. Otherwise stop.

Columns listed in ``keep`` never move: they stay in their initial state, in or out
(MATLAB: "predictors to keep in their initial state"). Ties go to the lowest column
index. ``maxiter`` bounds the number of moves.

Reported ``b``, ``se`` and ``pval`` (length p) follow MATLAB: for a column in the final
model they come from the final model; for an excluded column they are the coefficient,
standard error and p-value that column would get if added alone to the final model.

Choices where MATLAB's documentation is silent
----------------------------------------------
* Collinearity: a column whose residual, after projecting out the intercept and the
  other model columns, has squared norm <= ``_COLLINEAR_TOL`` times its centred sum of
  squares (plus a rounding allowance, so constant columns count) is *aliased*. Its test
  is meaningless, so it gets ``pval = 1.0`` (never added, since penter < 1; if it was
  forced in through ``inmodel`` it is the first term removed), ``se = NaN``, and, when
  excluded, ``b = 0.0`` (adding it cannot change the fit). Nothing raises.
* A test with no error degrees of freedom left has ``pval = NaN``. If the current model
  already fits ``y`` exactly, excluded columns get ``b = se = 0`` and ``pval = NaN``.
  A NaN p-value never triggers a move.
* Rows with a NaN in ``X`` or ``y`` are dropped (as MATLAB); infinite values raise.
* If the deterministic procedure would revisit a model it already visited (a cycle,
  which MATLAB would repeat until ``maxiter``), it stops with a ``RuntimeWarning``.
* Column indices in this API are 0-based; the MATLAB-style messages
  (:attr:`StepRecord.message`, :meth:`StepwiseResult.report`) print 1-based column
  numbers exactly as MATLAB does, so they can be compared with its documentation.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy import stats as _st

__all__ = ["StepRecord", "StepwiseResult", "stepwisefit"]

_COLLINEAR_TOL = 1e-10  # relative squared residual norm below which a column is aliased


@dataclass(frozen=True)
class StepRecord:
    """One move of the procedure (one entry of MATLAB's ``history``).

    ``column`` is 0-based; ``pval`` is the p-value that justified the move (the
    added-variable p-value for an addition, the in-model p-value for a removal);
    ``rmse``, ``df0`` and ``inmodel`` (bool, shape (p,)) describe the model *after* it.
    """

    step: int
    action: Literal["added", "removed"]
    column: int
    pval: float
    rmse: float
    df0: int
    inmodel: np.ndarray

    @property
    def message(self) -> str:
        """MATLAB's display line, e.g. ``'Step 1, added column 4, p=0.000576232'``."""
        return f"Step {self.step}, {self.action} column {self.column + 1}, p={self.pval:g}"


@dataclass(frozen=True)
class StepwiseResult:
    """Result of :func:`stepwisefit`; MATLAB's outputs under MATLAB's names.

    Arrays of shape (p,), p = number of columns of X: ``inmodel`` (bool), ``b``,
    ``se``, ``pval``. ``wasnan`` has shape (n,) and marks the dropped input rows.
    Scalars describe the final model: ``intercept``, ``rmse``, ``nobs`` (rows used),
    ``dfe``/``df0`` (error/regression degrees of freedom), ``sse``, ``sstotal``,
    ``fstat``/``fpval`` (final model vs. intercept only). ``nextstep`` is the 0-based
    column the procedure would move next (``None`` when it stopped on its own).
    """

    inmodel: np.ndarray
    b: np.ndarray
    se: np.ndarray
    pval: np.ndarray
    intercept: float
    rmse: float
    history: tuple[StepRecord, ...]
    initial_inmodel: np.ndarray
    nextstep: int | None
    nobs: int
    dfe: int
    df0: int
    sse: float
    sstotal: float
    fstat: float
    fpval: float
    wasnan: np.ndarray
    penter: float
    premove: float

    @property
    def columns(self) -> tuple[int, ...]:
        """0-based indices of the columns in the final model."""
        return tuple(int(j) for j in np.flatnonzero(self.inmodel))

    def predict(self, X) -> np.ndarray:
        """Predictions ``intercept + X[:, inmodel] @ b[inmodel]``.

        X: shape (m, p) with the same columns as the fitted X, or (p,) for one row.
        Returns shape (m,) (or a 0-d array for a single row).
        """
        X = np.asarray(X, dtype=float)
        if X.shape[-1] != self.inmodel.size or X.ndim > 2:
            raise ValueError(f"X must have shape (m, {self.inmodel.size}); got {X.shape}")
        return self.intercept + X[..., self.inmodel] @ self.b[self.inmodel]

    def report(self) -> str:
        """MATLAB's ``'display','on'`` text: steps, final columns, coefficient table."""

        def cols(mask: np.ndarray) -> str:
            idx = np.flatnonzero(mask)
            return " ".join(str(j + 1) for j in idx) if idx.size else "none"

        lines = [f"Initial columns included: {cols(self.initial_inmodel)}"]
        lines += [rec.message for rec in self.history]
        lines.append(f"Final columns included: {cols(self.inmodel)}")
        lines.append(f"{'Coeff':>10} {'Std.Err.':>10} {'Status':>6} {'P':>12}")
        for j in range(self.inmodel.size):
            status = "In" if self.inmodel[j] else "Out"
            lines.append(f"{self.b[j]:>10.4f} {self.se[j]:>10.4f} {status:>6} {self.pval[j]:>12.5g}")
        return "\n".join(lines)


def _term_tests(Z: np.ndarray, C: np.ndarray, y: np.ndarray):
    """t-tests of each column of C when added alone to the model with design Z.

    Z: (n, m) design (intercept column included, may be rank deficient);
    C: (n, k) candidate columns; y: (n,). Returns arrays (b, se, pval) of shape (k,).
    By Frisch-Waugh-Lovell, b and se equal the coefficient and standard error of that
    column in the least-squares fit of y on [Z, C[:, i]].
    """
    coef, _, rank, _ = np.linalg.lstsq(Z, np.column_stack([y, C]), rcond=None)
    resid = np.column_stack([y, C]) - Z @ coef
    yr, Cr = resid[:, 0], resid[:, 1:]
    dfe = y.size - rank - 1  # error degrees of freedom of each enlarged model
    ss_c = np.einsum("ij,ij->j", Cr, Cr)
    centred = C - C.mean(axis=0)
    rounding = (y.size * np.finfo(float).eps) ** 2 * np.einsum("ij,ij->j", C, C)
    aliased = ss_c <= _COLLINEAR_TOL * np.einsum("ij,ij->j", centred, centred) + rounding
    if yr @ yr <= _COLLINEAR_TOL * np.sum((y - y.mean()) ** 2):  # Z already fits y exactly
        nan = np.full(ss_c.shape, np.nan)
        return np.zeros_like(ss_c), np.where(aliased, np.nan, 0.0), np.where(aliased, 1.0, nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        b = np.where(aliased, 0.0, (Cr.T @ yr) / ss_c)
        sse = np.einsum("ij,ij->j", yr[:, None] - Cr * b, yr[:, None] - Cr * b)
        se = np.sqrt(sse / dfe / ss_c) if dfe > 0 else np.full(b.shape, np.nan)
        t = b / se
    pval = 2.0 * _st.t.sf(np.abs(t), dfe) if dfe > 0 else np.full(b.shape, np.nan)
    pval = np.where(np.isnan(t), np.nan, pval)
    return b, np.where(aliased, np.nan, se), np.where(aliased, 1.0, pval)


def _fit(X: np.ndarray, y: np.ndarray, inmodel: np.ndarray) -> dict:
    """Fit y ~ 1 + X[:, inmodel]; per-column b, se, pval as MATLAB reports them."""
    n, p = X.shape
    Z = np.column_stack([np.ones(n), X[:, inmodel]])
    coef, _, rank, _ = np.linalg.lstsq(Z, y, rcond=None)
    sse = float(np.sum((y - Z @ coef) ** 2))
    b, se, pval = np.empty(p), np.empty(p), np.empty(p)
    out = np.flatnonzero(~inmodel)
    if out.size:
        b[out], se[out], pval[out] = _term_tests(Z, X[:, out], y)
    inn = np.flatnonzero(inmodel)
    b[inn] = coef[1:]
    for pos, j in enumerate(inn):  # in-model test of j = test of adding j to the rest
        Zj = np.delete(Z, pos + 1, axis=1)
        _, se_j, p_j = _term_tests(Zj, X[:, [j]], y)
        se[j], pval[j] = se_j[0], p_j[0]
    dfe, df0 = n - rank, rank - 1
    sstotal = float(np.sum((y - y.mean()) ** 2))
    with np.errstate(divide="ignore", invalid="ignore"):
        rmse = float(np.sqrt(sse / dfe)) if dfe > 0 else np.nan
        fstat = ((sstotal - sse) / df0) / (sse / dfe) if df0 > 0 and dfe > 0 else np.nan
    fpval = float(_st.f.sf(fstat, df0, dfe)) if np.isfinite(fstat) else np.nan
    return dict(
        b=b,
        se=se,
        pval=pval,
        intercept=float(coef[0]),
        rmse=rmse,
        sse=sse,
        dfe=int(dfe),
        df0=int(df0),
        sstotal=sstotal,
        fstat=float(fstat),
        fpval=fpval,
    )


def _next_move(inmodel, pval, movable, penter, premove) -> int | None:
    """MATLAB's rule: best addition if p < penter, else worst removal if p > premove."""
    cand = np.flatnonzero(~inmodel & movable & ~np.isnan(pval))
    if cand.size and pval[cand].min() < penter:
        return int(cand[np.argmin(pval[cand])])
    cand = np.flatnonzero(inmodel & movable & ~np.isnan(pval))
    if cand.size and pval[cand].max() > premove:
        return int(cand[np.argmax(pval[cand])])
    return None


def _column_mask(spec, p: int, name: str) -> np.ndarray:
    """A bool mask of shape (p,) from None, a bool vector, or 0-based column indices."""
    if spec is None:
        return np.zeros(p, dtype=bool)
    arr = np.asarray(spec)
    if arr.dtype == bool:
        if arr.shape != (p,):
            raise ValueError(f"{name} as a boolean mask must have shape ({p},); got {arr.shape}")
        return arr.copy()
    if arr.size and (not np.issubdtype(arr.dtype, np.integer) or arr.min() < 0 or arr.max() >= p):
        raise ValueError(f"{name} must be a boolean mask or 0-based column indices in [0, {p})")
    mask = np.zeros(p, dtype=bool)
    mask[arr.astype(int).ravel()] = True
    return mask


def _check_probabilities(penter, premove) -> tuple[float, float]:
    for name, v in (("penter", penter), ("premove", premove)):
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
            raise ValueError(f"{name} must be a number in (0, 1); got {v!r}")
        if not 0.0 < float(v) < 1.0:
            raise ValueError(f"{name} must be a p-value threshold in (0, 1); got {v!r}")
    if penter > premove:
        raise ValueError(
            f"penter ({penter}) must be <= premove ({premove}), as MATLAB's stepwisefit "
            "requires; otherwise a term could be added and removed forever"
        )
    return float(penter), float(premove)


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a)
    a.setflags(write=False)
    return a


def stepwisefit(
    X,
    y,
    penter: float = 0.05,
    premove: float = 0.10,
    inmodel=None,
    maxiter: int | None = None,
    keep=None,
) -> StepwiseResult:
    """Stepwise regression of ``y`` on the columns of ``X``, as MATLAB's ``stepwisefit``.

    Parameters
    ----------
    X : array_like, shape (n, p)
        Candidate predictors, one term per column; no column of ones (the intercept is
        always in the model).
    y : array_like, shape (n,) (or (n, 1))
        Response. Rows with a NaN in ``X`` or ``y`` are dropped.
    penter, premove : float
        Add a term if its added-variable p-value is ``< penter``; remove one if its
        p-value is ``> premove``. Need ``0 < penter <= premove < 1``.
    inmodel : None, bool array of shape (p,), or sequence of 0-based column indices
        Initial model (default: intercept only).
    maxiter : int or None
        Maximum number of moves (default: no limit). ``0`` fits the initial model only.
    keep : None, bool array of shape (p,), or sequence of 0-based column indices
        Columns that keep their initial state (in or out) throughout.

    Returns
    -------
    StepwiseResult
        Frozen; see its docstring. ``result.history`` lists the moves in order.
    """
    penter, premove = _check_probabilities(penter, premove)
    X = np.asarray(X, dtype=float)
    y = np.asarray(y, dtype=float)
    if y.ndim == 2 and y.shape[1] == 1:
        y = y[:, 0]
    if X.ndim != 2 or y.ndim != 1 or X.shape[0] != y.shape[0] or X.shape[1] == 0:
        raise ValueError(f"need X of shape (n, p>=1) and y of shape (n,); got {X.shape} and {y.shape}")
    if np.isinf(X).any() or np.isinf(y).any():
        raise ValueError("X and y must not contain infinite values")
    p = X.shape[1]
    if maxiter is not None and (isinstance(maxiter, bool) or int(maxiter) != maxiter or maxiter < 0):
        raise ValueError(f"maxiter must be a non-negative integer or None; got {maxiter!r}")
    limit = np.inf if maxiter is None else int(maxiter)
    start = _column_mask(inmodel, p, "inmodel")
    movable = ~_column_mask(keep, p, "keep")

    wasnan = np.isnan(X).any(axis=1) | np.isnan(y)
    X, y = X[~wasnan], y[~wasnan]
    if y.size < 2:
        raise ValueError(f"need at least 2 rows without NaN; got {y.size}")

    current = start.copy()
    fit = _fit(X, y, current)
    history: list[StepRecord] = []
    visited = {current.tobytes()}
    while True:
        move = _next_move(current, fit["pval"], movable, penter, premove)
        if move is None or len(history) >= limit:
            break
        trial = current.copy()
        trial[move] = not trial[move]
        if trial.tobytes() in visited:
            warnings.warn(
                f"stepwisefit: moving column {move} would revisit an earlier model (a cycle); stopping",
                RuntimeWarning,
                stacklevel=2,
            )
            break
        action = "removed" if current[move] else "added"
        pmove = float(fit["pval"][move])
        current = trial
        visited.add(current.tobytes())
        fit = _fit(X, y, current)
        history.append(
            StepRecord(
                step=len(history) + 1,
                action=action,
                column=move,
                pval=pmove,
                rmse=fit["rmse"],
                df0=fit["df0"],
                inmodel=_frozen(current),
            )
        )

    return StepwiseResult(
        inmodel=_frozen(current),
        b=_frozen(fit["b"]),
        se=_frozen(fit["se"]),
        pval=_frozen(fit["pval"]),
        intercept=fit["intercept"],
        rmse=fit["rmse"],
        history=tuple(history),
        initial_inmodel=_frozen(start),
        nextstep=move,
        nobs=int(y.size),
        dfe=fit["dfe"],
        df0=fit["df0"],
        sse=fit["sse"],
        sstotal=fit["sstotal"],
        fstat=fit["fstat"],
        fpval=fit["fpval"],
        wasnan=_frozen(wasnan),
        penter=penter,
        premove=premove,
    )
