"""Nano models with thermal terms: Eq. (5.2), Eq. (5.3)-(5.5) and Eq. (5.10).

Temperatures t_i are the raw thermocouple readings in degC, as in the thesis (not
differences to a reference: the bias b_0 / lambda absorbs the reference, and higher-order
or humidity terms did not help, Sec. 5.2.2). They are centred internally before the
regression, which changes nothing but the conditioning.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calflow.nano.models.geometric import Nano1DModel, _Model
from calflow.nano.models.terms import (
    ModelInputError,
    _check_order,
    as_temperatures,
    as_vector,
    geometric_specs,
    identify,
    temperature_stats,
    thermal_specs,
)

__all__ = ["ThermalDriftModel", "SingleModel", "TwoDoFModel"]


def _temps_for_fit(temperatures, n: int, who: str) -> np.ndarray:
    t = as_temperatures(temperatures, n, None, who, allow_nan=True)
    if t.shape[1] == 0:
        raise ModelInputError(f"{who}: need at least one temperature channel")
    return np.array(t)


@dataclass(frozen=True, eq=False)
class _Thermal1D(Nano1DModel):
    """A 1-DoF model whose x-independent part is ``sum_i b_i t_i + bias`` (um)."""

    bias_name = "lambda"

    def thermal(self) -> np.ndarray:
        return np.array([self.value(f"b_{i}") for i in range(1, len(self.sensors) + 1)])

    def offset(self, temperatures, n: int) -> np.ndarray:
        t = as_temperatures(temperatures, n, len(self.sensors), f"{self.kind} model")
        return t @ self.thermal() + self.value(self.bias_name)


@dataclass(frozen=True, eq=False)
class ThermalDriftModel(_Thermal1D):
    """Thermal-drift model, Eq. (5.2): ``q_t = sum_{i=1}^{n2} b_i t_i + b_0``.

    q_t (um) is the thermal *compensation input*, so it is fitted to minus the drift that
    the external sensor sees on a stage at rest (Fig. 5.2): ``q_t = -delta``. b_i in
    um/degC, b_0 (bias) in um; n2 is the number of thermocouples (the thesis calls it the
    "order", but the model is first order in each t_i; higher orders did not help). Terms are selected by stepwise regression. As a stand-alone model it
    assumes an ideal geometry: ``command = x_T + q_t(t)``.
    """

    kind = "thermal"
    bias_name = "b_0"

    @classmethod
    def fit(
        cls, temperatures, drift, *, select="stepwise", penter=0.05, premove=0.10, force=(), sensors=None
    ) -> ThermalDriftModel:
        """Fit Eq. (5.2): temperatures (n, k) degC, drift (n,) um of a stage at rest."""
        d = np.asarray(drift, dtype=float).ravel()
        t = _temps_for_fit(temperatures, d.size, "ThermalDriftModel.fit")
        k = t.shape[1]
        terms, info = identify(
            t,
            thermal_specs(k),
            -d,
            ("b_0", "um", "bias of the thermal model"),
            select=select,
            penter=penter,
            premove=premove,
            force=force,
            shift=np.nanmean(t, axis=0),
        )
        return cls(terms=terms, info=info, **temperature_stats(t, sensors, k))

    def poly(self) -> np.ndarray:
        return np.array([0.0, 1.0])

    def compensation(self, temperatures) -> np.ndarray:
        """q_t (um) of Eq. (5.2) for temperature readings (k,) or (n, k)."""
        n = np.atleast_2d(np.asarray(temperatures, dtype=float)).shape[0]
        return self.offset(temperatures, n)

    def drift(self, temperatures) -> np.ndarray:
        """Predicted drift delta = -q_t (um)."""
        return -self.compensation(temperatures)


@dataclass(frozen=True, eq=False)
class SingleModel(_Thermal1D):
    """Single model, Eq. (5.3): ``q = sum_{i=1}^{n1} a_i x**i + sum_{i=1}^{n2} b_i t_i + lambda``.

    Geometric part of Eq. (5.1) without a_0 plus the thermal part of Eq. (5.2) without
    b_0; lambda = a_0 + b_0 (um). Identified in one stepwise regression of the stacked
    training poses, Eq. (5.4)-(5.5): q_m ~ [x_m, x_m**2, ..., x_m**n1, t_1m, ..., t_n2m].
    Commanding needs the current temperatures; it extrapolates outside the training
    temperature range (see :meth:`in_training_range`), the weakness KMZ addresses.

    Thesis Table 5.1 prints a_1 = 2.454e-8, a_2 = -2.167e-5, a_3 = 1.005: the geometric
    values are in descending-power order (MATLAB ``polyfit`` style), since a gain of 1.005
    can only be the coefficient of x. Here a_i always multiplies x**i (unit um**(1-i)).
    """

    kind = "single"

    @classmethod
    def fit(
        cls,
        command,
        measured,
        temperatures,
        *,
        order: int = 3,
        select="stepwise",
        penter=0.05,
        premove=0.10,
        force=("a_1",),
        sensors=None,
    ) -> SingleModel:
        """Fit Eq. (5.5): command q (n,), measured x (n,) in um, temperatures (n, k) degC.

        ``force`` terms are kept in (stepwise ``keep``): by default the gain a_1, without
        which the model could not be inverted.
        """
        order = _check_order(order)
        q = np.asarray(command, dtype=float).ravel()
        x = np.asarray(measured, dtype=float).ravel()
        if q.shape != x.shape:
            raise ModelInputError(f"command and measured differ in length ({q.size} vs {x.size})")
        t = _temps_for_fit(temperatures, q.size, "SingleModel.fit")
        k = t.shape[1]
        s = float(np.nanmax(np.abs(x))) or 1.0
        cols = np.column_stack([x**i for i in range(1, order + 1)] + list(t.T))
        terms, info = identify(
            cols,
            geometric_specs(order) + thermal_specs(k),
            q,
            ("lambda", "um", "offset lambda = a_0 + b_0"),
            select=select,
            penter=penter,
            premove=premove,
            force=force,
            scale=np.concatenate([s ** np.arange(1, order + 1), np.ones(k)]),
            shift=np.concatenate([np.zeros(order), np.nanmean(t, axis=0)]),
        )
        return cls(terms=terms, info={**info, "order": order}, **temperature_stats(t, sensors, k))

    def poly(self) -> np.ndarray:
        return np.array([0.0] + [self.value(f"a_{i}") for i in range(1, self.info["order"] + 1)])


# ----------------------------------------------------------------------------- Eq. (5.10)
class TwoDoFModel(_Model):
    """2-DoF model, Eq. (5.10), one equation per joint j in {x, y}::

        q_j = sum_{i=1}^{n1} a_ij x**i + sum_{i=1}^{n2} b_ij y**i
              + sum_{i=1}^{n3} c_ij t_i + lambda_j

    a_ij: effect of X motion on axis j, b_ij: of Y motion, c_ij (um/degC): thermal drift,
    lambda_j (um): offset. Note that Eq. (5.10) reuses n2 and b for the Y-motion terms;
    its thermal coefficients are c_ij over n3 thermocouples. Cross-coupling is additive
    (the thesis has no x*y terms); with no temperatures, n3 = 0. Each equation is
    identified separately by stepwise regression, forcing in the direct gains a_1x, b_1y.
    Commanding is one evaluation per axis; :meth:`position` inverts it (2-D Newton).
    """

    kind = "two_dof"

    @classmethod
    def fit(
        cls,
        command,
        measured,
        temperatures=None,
        *,
        order=(3, 3),
        select="stepwise",
        penter=0.05,
        premove=0.10,
        force=("a_1x", "b_1y"),
        sensors=None,
    ) -> TwoDoFModel:
        """Fit Eq. (5.10): command (n, 2) [q_x, q_y], measured (n, 2) [x, y], temps (n, k)."""
        n1, n2 = (_check_order(o) for o in order)
        q, xy = np.asarray(command, float), np.asarray(measured, float)
        if q.ndim != 2 or q.shape[1] != 2 or xy.shape != q.shape:
            raise ModelInputError(f"command and measured must both be (n, 2); got {q.shape}, {xy.shape}")
        cols = [xy[:, 0] ** i for i in range(1, n1 + 1)] + [xy[:, 1] ** i for i in range(1, n2 + 1)]
        s = np.nanmax(np.abs(xy), axis=0)
        s = np.where(s > 0, s, 1.0)
        scale = [s[0] ** i for i in range(1, n1 + 1)] + [s[1] ** i for i in range(1, n2 + 1)]
        shift = [0.0] * len(cols)
        k, kw = 0, {}
        if temperatures is not None:
            t = as_temperatures(temperatures, q.shape[0], None, "TwoDoFModel.fit", allow_nan=True)
            k = t.shape[1]
            cols += list(t.T)
            scale += [1.0] * k
            shift += list(np.nanmean(t, axis=0))
            kw = temperature_stats(t, sensors, k)
        terms, infos = (), {}
        for j, axis in enumerate("xy"):
            specs = (
                geometric_specs(n1, axis) + geometric_specs(n2, axis, "b", "y") + thermal_specs(k, "c", axis)
            )
            ax_terms, info = identify(
                np.column_stack(cols),
                specs,
                q[:, j],
                (f"lambda_{axis}", "um", f"offset of q_{axis}"),
                select=select,
                penter=penter,
                premove=premove,
                force=[f for f in force if f.endswith(axis)],
                scale=scale,
                shift=shift,
            )
            terms += ax_terms
            infos.update({f"{key}_{axis}": v for key, v in info.items()})
        info = {**infos, "order_x": n1, "order_y": n2, "n_temperatures": k}
        return cls(terms=terms, info=info, **kw)

    def _split(self, axis):
        n1, n2, k = self.info["order_x"], self.info["order_y"], self.info["n_temperatures"]
        a = np.array([0.0] + [self.value(f"a_{i}{axis}") for i in range(1, n1 + 1)])
        b = np.array([0.0] + [self.value(f"b_{i}{axis}") for i in range(1, n2 + 1)])
        c = np.array([self.value(f"c_{i}{axis}") for i in range(1, k + 1)])
        return a, b, c, self.value(f"lambda_{axis}")

    def _xy(self, name, xy) -> np.ndarray:
        arr = np.asarray(xy, dtype=float)
        arr = arr[None, :] if arr.ndim == 1 else arr
        if arr.ndim != 2 or arr.shape[1] != 2:
            raise ModelInputError(f"{name} must have shape (2,) or (n, 2) (um); got {np.shape(xy)}")
        as_vector(name, arr.ravel())
        return arr

    def _const(self, temperatures, n) -> np.ndarray:
        k = self.info["n_temperatures"]
        t = as_temperatures(temperatures, n, k, "TwoDoFModel") if k else np.zeros((n, 0))
        return np.column_stack([t @ self._split(ax)[2] + self._split(ax)[3] for ax in "xy"])

    def command(self, target, temperatures=None, reference=None) -> np.ndarray:
        """Joint commands (n, 2) [q_x, q_y] in um for targets (n, 2) [x_T, y_T], Eq. (5.10)."""
        if reference is not None:
            raise ModelInputError("Eq. (5.10) has no KMZ reference")
        xy = self._xy("target", target)
        pv = np.polynomial.polynomial.polyval
        geo = [pv(xy[:, 0], self._split(ax)[0]) + pv(xy[:, 1], self._split(ax)[1]) for ax in "xy"]
        return np.column_stack(geo) + self._const(temperatures, xy.shape[0])

    def position(self, command, temperatures=None) -> np.ndarray:
        """Forward map (n, 2): where commands (n, 2) land according to the model (Newton)."""
        q = self._xy("command", command)
        rhs = q - self._const(temperatures, q.shape[0])
        ab = [self._split(ax)[:2] for ax in "xy"]
        der = np.polynomial.polynomial.polyder
        pv = np.polynomial.polynomial.polyval
        J0 = np.array([[ab[j][0][1], ab[j][1][1]] for j in range(2)])
        p = np.linalg.solve(J0, rhs.T).T
        for _ in range(60):
            f = np.column_stack([pv(p[:, 0], a) + pv(p[:, 1], b) for a, b in ab]) - rhs
            J = np.stack([np.column_stack([pv(p[:, 0], der(a)), pv(p[:, 1], der(b))]) for a, b in ab], axis=1)
            step = np.linalg.solve(J, f[..., None])[..., 0]
            p = p - step
            if np.all(np.abs(step) <= 1e-11 * np.maximum(1.0, np.abs(p))):
                return p
        raise ModelInputError("TwoDoFModel: forward map did not converge")

    def predict_error(self, target, temperatures=None) -> np.ndarray:
        """Predicted (n, 2) error of the uncalibrated stage commanded with q = target (um)."""
        xy = self._xy("target", target)
        return self.position(xy, temperatures) - xy
