"""Adaptive model using kilometre-zero (KMZ), thesis Sec. 5.2.4, Eq. (5.6) and (5.7).

Principle (Sec. 5.2.4): thermal drift is position independent, so it can be measured at
one place and applied to the whole stroke. An absolute reference point, the KMZ, is
defined by a sensor (here the interferometer) or a fixed precise tool; the stage visits it,
the sensor reading there is recorded, and the change of that reading since the model's
own reference is the drift, which is compensated by a constant command offset:

    Eq. (5.6)   q = sum_{i=0}^{n1} a_i x**i + lambda_KMZ
    Eq. (5.7)   q = sum_{i=1}^{n1} a_i x**i + sum_{i=1}^{n2} b_i t_i + lambda + lambda_KMZ

The polynomial is the single model's geometric part (Sec. 5.2.4: "the same as that of the
single model"); the thesis experiments use Eq. (5.6).

How lambda_KMZ is computed here (:meth:`AdaptiveKMZModel.lambda_kmz`). A visit sends a
command q_K and the KMZ sensor measures x_K (um, in the model's frame, i.e. the frame
the training positions were measured in). The model without KMZ says that q_K puts the
stage at the x with ``base(x) = q_K``; it is at x_K instead, so the command offset that
makes the model consistent with the visit is

    lambda_KMZ = q_K - base(x_K)       (base = Eq. (5.6) or (5.7) without lambda_KMZ).

With a_1 ~ 1 this is -(x_K - x_expected): minus "the difference of the two measurements"
of the thesis's recipe, where the first measurement is the model's own prediction at the
KMZ. The sign matches the thesis's analysis of AP_A, where lambda_KMZ = -L_1(t) cancels the
drift L_1 seen at the first zero position. Because the visit is expressed through the
model, q_K need not equal the target used later, and a previous lambda_KMZ does not have to
be undone. For Eq. (5.6) the constant a_0 is not identifiable from the single model
(lambda = a_0 + b_0); it is set to lambda + sum_i b_i mean(t_i) (the single model at the
mean training temperatures) and is fully absorbed by lambda_KMZ.

Thesis slips resolved here: the printed AP_A derivation uses
q_c = x_T + g'(x_T) + L'(t) + lambda_KMZ, i.e. the Eq. (5.7) form, although the text says
the experiments use Eq. (5.6), and its third line drops L'(t); neither changes the result
that lambda_KMZ cancels the drift at the first zero position. "Compensated by adding the
calculated difference" is read with the sign of lambda_KMZ = -L_1(t).

When to visit: at the start of each test (the thesis's experiments: "lambda_KMZ is only
measured at the first zero position") or periodically; the revisit rate should follow the
temperature's magnitude and rate of change. :meth:`AdaptiveKMZModel.offsets_at` applies a
series of visits to a series of command times (zero-order hold: latest visit wins).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calflow.nano.models.terms import ModelInputError, Term, as_temperatures, as_vector, power_unit
from calflow.nano.models.thermal import SingleModel, _Thermal1D

__all__ = ["KMZReading", "AdaptiveKMZModel"]

VARIANTS = ("5.6", "5.7")


@dataclass(frozen=True)
class KMZReading:
    """One visit of the kilometre-zero.

    command: joint command sent (um); measured: KMZ sensor reading (um, model frame);
    temperatures: thermocouples at the visit (degC, shape (k,); needed for Eq. (5.7));
    time: when (s; needed only by :meth:`AdaptiveKMZModel.offsets_at`).
    """

    command: float
    measured: float
    temperatures: np.ndarray | None = None
    time: float | None = None


@dataclass(frozen=True, eq=False)
class AdaptiveKMZModel(_Thermal1D):
    """Adaptive model using KMZ, Eq. (5.6) (default) or Eq. (5.7); see the module docstring.

    ``command(target, temperatures=None, reference=...)``: ``reference`` is a
    :class:`KMZReading`, or lambda_KMZ itself (um; a scalar or one value per target, e.g.
    from :meth:`offsets_at`). It is required; ``reference=0.0`` uses the model's own
    constant (no drift update). Eq. (5.7) also needs the current temperatures.
    """

    kind = "adaptive_kmz"

    @property
    def variant(self) -> str:
        return self.info["variant"]

    @classmethod
    def from_single(cls, single: SingleModel, variant: str = "5.6") -> AdaptiveKMZModel:
        """Take the polynomial (and, for Eq. (5.7), the thermal part) of a single model."""
        if variant not in VARIANTS:
            raise ModelInputError(f"variant must be one of {VARIANTS}; got {variant!r}")
        info = {**single.info, "variant": variant}
        kw = {"sensors": single.sensors, "training_temperature": single.training_temperature}
        if variant == "5.7":
            return cls(terms=single.terms, info=info, **kw)
        t_mean = single.training_temperature[1]
        a0 = single.value("lambda") + float(t_mean @ single.thermal())
        geo = tuple(t for t in single.terms if t.name.startswith("a_"))
        a0_term = Term(
            "a_0", power_unit(0), "a_0 = lambda + sum_i b_i mean(t_i) (absorbed by lambda_KMZ)", a0
        )
        return cls(terms=(a0_term,) + geo, info=info, **kw)

    @classmethod
    def from_geometric(cls, geometric) -> AdaptiveKMZModel:
        """Eq. (5.6) on top of a geometric model, Eq. (5.1), fitted on its own."""
        return cls(terms=geometric.terms, info={**geometric.info, "variant": "5.6"})

    @classmethod
    def fit(cls, command, measured, temperatures, *, variant: str = "5.6", **kwargs):
        """Fit the single model, Eq. (5.3)-(5.5), on training data and wrap it."""
        return cls.from_single(SingleModel.fit(command, measured, temperatures, **kwargs), variant)

    def poly(self) -> np.ndarray:
        first = 0 if self.variant == "5.6" else 1
        coefs = [self.value(f"a_{i}") for i in range(first, self.info["order"] + 1)]
        return np.array([0.0] * first + coefs)

    def offset(self, temperatures, n: int) -> np.ndarray:
        if self.variant == "5.6":
            return np.zeros(n)  # Eq. (5.6) has no thermal term; temperatures are ignored
        return super().offset(temperatures, n)

    def lambda_kmz(self, reading: KMZReading) -> float:
        """lambda_KMZ (um) from one KMZ visit: q_K - base(x_K) (module docstring)."""
        q_k = as_vector("KMZReading.command", reading.command)
        x_k = as_vector("KMZReading.measured", reading.measured)
        if q_k.size != 1 or x_k.size != 1:
            raise ModelInputError("a KMZReading holds one visit (scalar command and measured)")
        temps = None
        if self.variant == "5.7":
            temps = as_temperatures(reading.temperatures, 1, len(self.sensors), "KMZ reading for Eq. (5.7)")
        base = np.polynomial.polynomial.polyval(x_k, self.poly()) + self.offset(temps, 1)
        return float(q_k[0] - base[0])

    def reference_offset(self, reference, n: int) -> np.ndarray:
        if reference is None:
            raise ModelInputError(
                "adaptive KMZ model needs reference= (a KMZReading or "
                "lambda_KMZ in um); pass 0.0 to use the training constant"
            )
        if isinstance(reference, KMZReading):
            return np.full(n, self.lambda_kmz(reference))
        lam = as_vector("reference (lambda_KMZ)", reference, n)
        return np.broadcast_to(lam, (n,)).astype(float)

    def offsets_at(self, times, readings) -> np.ndarray:
        """lambda_KMZ (um) in force at each time (s): that of the latest visit at or before it."""
        t = as_vector("times", times)
        if not readings:
            raise ModelInputError("offsets_at needs at least one KMZReading")
        if any(r.time is None or not np.isfinite(r.time) for r in readings):
            raise ModelInputError("every KMZReading passed to offsets_at needs a finite time (s)")
        order = sorted(readings, key=lambda r: r.time)
        visit_times = np.array([r.time for r in order])
        idx = np.searchsorted(visit_times, t, side="right") - 1
        if (idx < 0).any():
            raise ModelInputError(f"time {t[idx < 0][0]} s precedes the first KMZ visit ({visit_times[0]} s)")
        return np.array([self.lambda_kmz(r) for r in order])[idx]
