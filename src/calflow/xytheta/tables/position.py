"""Lookup-table compensation of the XY position errors (Sec. 4.4.2).

PositionLUT — Eq. (4.14)/(4.15), Fig. 4.10, 4.11, 4.14
------------------------------------------------------
Tables (µm) from ``calflow.xytheta.tables.characterisation.characterise``, indexed by the commanded joint
position of the moving stage; errors are *target − measured* in the stage frame
(u ≈ X, v ≈ Y). For joint positions (X, Y) approached in directions (d_x, d_y)::

    ex = [f_xx | b_xx](X) + δx(Y) + [f_yx | b_yx](Y)         (4.14)
    ey = [f_xy | b_xy](X) + δy(X) + [f_yy | b_yy](Y)         (4.15; δy = trend of f_xy)

forward tables f_.. for d = +1, backward b_.. for d = -1. The stage reaches X - ex
(Eq. 4.18), so the command that lands on target x_T solves X = x_T + ex(X, Y): commanding
*target + error* (Eq. 4.19 adds ex; the thesis text's "minus" is the other sign
convention). :meth:`PositionLUT.compensate` solves it by fixed-point iteration (the
tables' slopes are ≲ 0.06, so it contracts); ``iterations=1`` is the thesis' one-shot
``x_T + ex(x_T, y_T)`` (tables read at the target), which on a rig whose stages are
misaligned by a few degrees leaves µm-level residuals (see tests/xytheta/test_lookup.py).

Interpolation: ``"linear"`` (numpy.interp) or ``"cubic"`` (scipy CubicSpline, not-a-knot),
over the finite table entries. Outside a table: ``bounds="error"`` (default) raises a
ValueError naming the axis and range; ``bounds="clamp"`` uses the end value. δx, δy are
straight lines and valid everywhere.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import xarray as xr
from scipy.interpolate import CubicSpline

from calflow.data.runs import RunMetadata

METHODS = ("linear", "cubic")
BOUNDS = ("error", "clamp")


def _interpolator(pos: np.ndarray, values: np.ndarray, method: str, what: str, bounds: str) -> Callable:
    """Callable q -> table value over the finite entries of ``values`` at ``pos``."""
    ok = np.isfinite(pos) & np.isfinite(values)
    p, v = pos[ok], values[ok]
    if p.size < 2:
        raise ValueError(f"{what}: fewer than 2 finite table entries")
    if method == "linear":
        base = lambda q: np.interp(q, p, v)  # noqa: E731
    elif method == "cubic":
        base = CubicSpline(p, v, bc_type="not-a-knot", extrapolate=False)
    else:
        raise ValueError(f"interpolation method: expected one of {METHODS}, got {method!r}")
    lo, hi = float(p[0]), float(p[-1])

    def f(q):
        q = np.asarray(q, dtype=float)
        if bounds == "clamp":
            return base(np.clip(q, lo, hi))
        tol = 1e-9 * max(1.0, abs(lo), abs(hi))
        bad = (q < lo - tol) | (q > hi + tol)
        if np.any(bad):
            raise ValueError(
                f"{what}: position {float(q[bad].flat[0]):.3f} outside the table "
                f"[{lo:g}, {hi:g}]; characterise a longer stroke or use bounds='clamp'"
            )
        return base(np.clip(q, lo, hi))

    return f


def _check_directions(d, name: str) -> np.ndarray:
    d = np.asarray(d)
    if not np.all(np.isin(d, (-1, 1))):
        raise ValueError(
            f"{name}: expected +1 (forward) or -1 (backward) everywhere; infer them with infer_directions"
        )
    return d


def infer_directions(values, start: float = 0.0, initial: int = 1) -> np.ndarray:
    """Approach direction (±1) of each value of a sequence, Fig. 4.10.

    d_k = sign(v_k − v_{k−1}) with v_{−1} = ``start``; no change keeps the previous
    direction (``initial`` before the first move), as the stage keeps its last approach.
    """
    v = np.concatenate([[float(start)], np.asarray(values, dtype=float).ravel()])
    step = np.sign(np.diff(v))
    out = np.empty(step.size, dtype=np.int8)
    prev = 1 if initial >= 0 else -1
    for i, s in enumerate(step):
        prev = int(s) if s != 0 else prev
        out[i] = prev
    return out


def sequential_commands(compensate, x_T, y_T, start=(0.0, 0.0), start_direction=(1, 1)):
    """Commands whose approach directions agree with the stage's own (sign of command change).

    Walks the targets in order; at each one tries the direction pairs (Fig. 4.10 guess
    first) and keeps the first whose commands ``compensate(x_T, y_T, d_x, d_y)`` move
    each axis in its assumed direction. When no direction fits an axis (its target moves
    less than the backlash gap, e.g. X on the square's BC side) the axis is held: same
    command, same direction. Returns X, Y (µm) and d_x, d_y (int8).

    ``compensate`` must act element by element (a target's command depends on that target
    and its directions only): it is called once per direction pair for all the targets,
    not four times per target — the same numbers, two orders of magnitude fewer calls.
    """
    x_T, y_T = np.asarray(x_T, dtype=float).ravel(), np.asarray(y_T, dtype=float).ravel()
    n = x_T.size
    every = {}  # (d_x, d_y) -> commands X, Y of every target approached in that pair
    for pair in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        cx, cy = compensate(x_T, y_T, np.full(n, pair[0]), np.full(n, pair[1]))
        every[pair] = (np.ravel(cx), np.ravel(cy))
    X, Y = np.empty(n), np.empty(n)
    DX, DY = np.empty(n, dtype=np.int8), np.empty(n, dtype=np.int8)
    xp, yp = float(start[0]), float(start[1])
    dxp, dyp = int(start_direction[0]), int(start_direction[1])
    txp, typ = xp, yp

    def call(k, sx, sy):
        cx, cy = every[(sx, sy)]
        return float(cx[k]), float(cy[k])

    def fits(c, prev, d, dprev):
        return (c > prev and d > 0) or (c < prev and d < 0) or (c == prev and d == dprev)

    for k in range(n):
        gx = int(np.sign(x_T[k] - txp)) or dxp
        gy = int(np.sign(y_T[k] - typ)) or dyp
        combos = [(gx, gy), (gx, -gy), (-gx, gy), (-gx, -gy)]
        results = {c: call(k, *c) for c in combos}
        chosen = next(
            (c for c in combos if fits(results[c][0], xp, c[0], dxp) and fits(results[c][1], yp, c[1], dyp)),
            None,
        )
        if chosen is not None:
            (cx, cy), (sx, sy) = results[chosen], chosen
        else:
            hold_x = not any(fits(results[c][0], xp, c[0], dxp) for c in combos)
            hold_y = not any(fits(results[c][1], yp, c[1], dyp) for c in combos)
            sx = dxp if hold_x else next(c[0] for c in combos if fits(results[c][0], xp, c[0], dxp))
            sy = dyp if hold_y else next(c[1] for c in combos if fits(results[c][1], yp, c[1], dyp))
            cx, cy = call(k, sx, sy)
            cx, cy = (xp if hold_x else cx), (yp if hold_y else cy)
        X[k], Y[k], DX[k], DY[k] = cx, cy, sx, sy
        xp, yp, dxp, dyp, txp, typ = cx, cy, sx, sy, x_T[k], y_T[k]
    return X, Y, DX, DY


@dataclass(frozen=True, eq=False)
class PositionLUT:
    """Position-dependent error tables of the XY stages, Eq. (4.14)/(4.15).

    ``xx``, ``xy`` have shape (len(x_position), 2) and ``yx``, ``yy`` (len(y_position), 2),
    column 0 forward (f_..), column 1 backward (b_..), in µm; ``xy`` and ``yx`` without
    their linear trends δy(x) = delta_y[0] + delta_y[1]·X and δx(y) = delta_x[0] +
    delta_x[1]·Y (intercept µm, slope µm/µm).
    """

    x_position: np.ndarray
    y_position: np.ndarray
    xx: np.ndarray
    xy: np.ndarray
    yx: np.ndarray
    yy: np.ndarray
    delta_x: tuple[float, float] = (0.0, 0.0)
    delta_y: tuple[float, float] = (0.0, 0.0)
    bounds: str = "error"
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.bounds not in BOUNDS:
            raise ValueError(f"PositionLUT.bounds: expected one of {BOUNDS}, got {self.bounds!r}")
        for name, pos in (
            ("xx", self.x_position),
            ("xy", self.x_position),
            ("yx", self.y_position),
            ("yy", self.y_position),
        ):
            if np.shape(getattr(self, name)) != (len(pos), 2):
                raise ValueError(
                    f"PositionLUT.{name}: expected shape ({len(pos)}, 2), got {np.shape(getattr(self, name))}"
                )

    def _table(self, name: str, q, d, method: str) -> np.ndarray:
        pos = self.x_position if name[0] == "x" else self.y_position
        out = []
        for col in (0, 1):
            key = (name, col, method)
            if key not in self._cache:
                label = f"{'XY'['xy'.index(name[0])]} table {name} ({'forward' if col == 0 else 'backward'})"
                self._cache[key] = _interpolator(
                    np.asarray(pos, float),
                    np.asarray(getattr(self, name))[:, col],
                    method,
                    label,
                    self.bounds,
                )
            out.append(self._cache[key])
        fwd, bwd = d > 0, d < 0
        res = np.zeros(np.shape(q))
        if fwd.any():
            res[fwd] = out[0](q[fwd])
        if bwd.any():
            res[bwd] = out[1](q[bwd])
        return res

    def errors(
        self, x, y, dir_x, dir_y, method: str = "linear", trends: bool = True
    ) -> tuple[np.ndarray, np.ndarray]:
        """ex, ey (µm) at joint positions x, y (µm) approached in dir_x, dir_y (±1), Eq. (4.14)/(4.15).

        ``trends=False`` gives the stages' own errors along and across their travel, for use
        inside a kinematic model (Models III, V), where the stage alignment and the
        perpendicularity are the parameters α and β, identified with the tables applied, and
        must not be counted twice. It leaves out the straight lines δx(y), δy(x) *and* the
        cosine error they imply on the along-travel tables: a stage at angle φ to the
        pattern's axis (tan φ the slope of the other axis's trend) is read as X cos φ when it
        is at X, so its table holds X (1 − cos φ) on top of its own error — 7.7 µm at 9.45 mm
        for the thesis rig's 2.3° — which the rotation by α already accounts for. And it is
        zero at the home joint (0, 0) approached forward: the world frame's origin is the
        home pose (Eq. 4.27), and a table referenced to one home reading carries that
        reading's noise as an offset of every joint, which rotates with Θ.
        """
        x, y, dx, dy = np.broadcast_arrays(
            np.asarray(x, float),
            np.asarray(y, float),
            _check_directions(dir_x, "dir_x"),
            _check_directions(dir_y, "dir_y"),
        )
        ex = self._table("xx", x, dx, method) + self._table("yx", y, dy, method)
        ey = self._table("xy", x, dx, method) + self._table("yy", y, dy, method)
        if trends:
            return ex + self.delta_x[0] + self.delta_x[1] * y, ey + self.delta_y[0] + self.delta_y[1] * x
        cos_x, cos_y = 1.0 / np.hypot(1.0, self.delta_y[1]), 1.0 / np.hypot(1.0, self.delta_x[1])
        one = np.ones(1)  # the home joint (0, 0), approached forward: the world frame's origin
        ex0 = self._table("xx", 0 * one, one, method) + self._table("yx", 0 * one, one, method)
        ey0 = self._table("xy", 0 * one, one, method) + self._table("yy", 0 * one, one, method)
        return ex - ex0[0] - x * (1.0 - cos_x), ey - ey0[0] - y * (1.0 - cos_y)

    def compensate(
        self, x_T, y_T, dir_x, dir_y, method: str = "linear", iterations: int = 6, trends: bool = True
    ) -> tuple[np.ndarray, np.ndarray]:
        """Joint commands X, Y (µm) that bring the stage onto targets x_T, y_T (Fig. 4.11).

        Fixed point of X = x_T + ex(X, Y), Y = y_T + ey(X, Y) (see module docstring);
        ``iterations=1`` gives the thesis' x_T + ex(x_T, y_T).
        """
        x_T, y_T = np.asarray(x_T, dtype=float), np.asarray(y_T, dtype=float)
        X, Y = x_T, y_T
        for _ in range(max(1, int(iterations))):
            ex, ey = self.errors(X, Y, dir_x, dir_y, method, trends)
            X, Y = x_T + ex, y_T + ey
        return X, Y

    @classmethod
    def from_dataset(cls, ds: xr.Dataset, bounds: str = "error") -> PositionLUT:
        """From a ``characterise`` result or a ``to_dataset`` file (direction [+1, -1])."""

        def tab(name: str) -> np.ndarray:
            return ds[name].sel(direction=[1, -1]).transpose(..., "direction").values.astype(float)

        return cls(
            ds["x_position"].values.astype(float),
            ds["y_position"].values.astype(float),
            tab("err_xx"),
            tab("err_xy"),
            tab("err_yx"),
            tab("err_yy"),
            (float(ds["delta_x_intercept"]), float(ds["delta_x_slope"])),
            (float(ds["delta_y_intercept"]), float(ds["delta_y_slope"])),
            bounds,
        )

    def to_dataset(self, meta: RunMetadata | None = None) -> xr.Dataset:
        """The tables as a ``calflow_kind = "luts"`` dataset (``from_dataset`` reads it back)."""

        def var(data, dims, units, long_name):
            return xr.Variable(
                dims, np.asarray(data, dtype=float), attrs={"units": units, "long_name": long_name}
            )

        xd, yd = ("x_position", "direction"), ("y_position", "direction")
        ds = xr.Dataset(
            {
                "err_xx": var(self.xx, xd, "um", "x error while X moves: f_xx, b_xx (Eq. 4.14)"),
                "err_xy": var(
                    self.xy, xd, "um", "y error while X moves minus delta_y: f_xy, b_xy (Eq. 4.15)"
                ),
                "err_yx": var(
                    self.yx, yd, "um", "x error while Y moves minus delta_x: f_yx, b_yx (Eq. 4.14)"
                ),
                "err_yy": var(self.yy, yd, "um", "y error while Y moves: f_yy, b_yy (Eq. 4.15)"),
                "delta_x_intercept": var(self.delta_x[0], (), "um", "intercept of delta_x(y) (Eq. 4.14)"),
                "delta_x_slope": var(self.delta_x[1], (), "1", "slope of delta_x(y) (Eq. 4.14)"),
                "delta_y_intercept": var(self.delta_y[0], (), "um", "intercept of delta_y(x)"),
                "delta_y_slope": var(self.delta_y[1], (), "1", "slope of delta_y(x)"),
            },
            coords={
                "x_position": var(self.x_position, ("x_position",), "um", "commanded X joint position"),
                "y_position": var(self.y_position, ("y_position",), "um", "commanded Y joint position"),
                "direction": xr.Variable(
                    ("direction",),
                    np.array([1, -1], dtype=np.int8),
                    attrs={"units": "1", "long_name": "approach direction (+1 forward, -1 backward)"},
                ),
            },
            attrs=meta.attrs("luts") if meta is not None else {},
        )
        ds.attrs["error_convention"] = "target - measured; command = target + error"
        return ds
