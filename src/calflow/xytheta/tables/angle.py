"""The angle table g_ax(Θ), g_ay(Θ) of Sec. 4.5, indexed by Θ alone (Eq. 4.18, 4.19).

"We choose a lookup table to construct g_ax(Θ) and g_ay(Θ) with corresponding Θ. And,
of course, interpolation might be needed if angle Θ is not a part of the lookup table."

calflow builds it from an angle characterisation (:func:`calflow.xytheta.plans.sweeps.angle_sweep`):
Θ swept forward and backward in fine steps at a few positions that no validation visits,
through a base model (II or III). The residual f = measured − target (world frame,
Eq. 4.27), taken relative to its value at the lowest swept angle at each position (what
is left there is that position's error, not an angle error), is averaged over positions
and cycles into one curve per direction. Its
amplitude spectrum decides the table's step: the shortest *significant* period (a spectral
peak above ``significance`` × the noise spectrum and ``min_fraction`` of the largest component) gets
at least ``samples_per_period`` tabulated angles. The noise spectrum is measured, not
assumed: the half-difference of the even and odd cycles' curves has the curve's noise and
none of its signal. When the sweep itself cannot give that many samples per period, or
significant content sits near its Nyquist frequency, the table *undersamples* the error
and says so (:attr:`AngleSpectrum.warning`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import xarray as xr

from calflow.xytheta.tables.angle_residuals import angle_fields, joint_increments

DIRECTIONS = (1, -1)  # rows of the tables: forward, backward


@dataclass(frozen=True)
class AngleSpectrum:
    """What the sweep says about the angle-dependent error (degree, µm)."""

    sweep_step_deg: float
    step_deg: float
    periods_deg: np.ndarray  # of the spectrum bins
    amplitude_um: np.ndarray
    noise_um: float  # RMS amplitude of the noise spectrum
    shortest_period_deg: float | None  # shortest significant period; None when nothing is significant
    interpolation_error_um: float  # bound on the linear-interpolation error of the significant components
    undersampled: bool
    warning: str = ""


def _bin_means(bins: np.ndarray, values: np.ndarray, size: int) -> np.ndarray:
    """Mean of ``values`` per bin index in ``range(size)``; NaN where a bin is empty."""
    count = np.bincount(bins, minlength=size)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, np.bincount(bins, weights=values, minlength=size) / count, np.nan)


def _curves(theta, f, direction, cycle, grid):
    """Mean of f (µm) over positions and cycles per (direction, grid angle), and the noise
    curve: half the difference of the even and the odd cycles' means. Shapes (2, len(grid)),
    rows in :data:`DIRECTIONS` order; NaN where a bin has no reading (noise: no even or no
    odd one). Readings off the grid or in another direction are ignored. One pass of
    :func:`numpy.bincount` over the readings, linear in their number."""
    f, direction, cycle = np.asarray(f, dtype=float), np.asarray(direction), np.asarray(cycle)
    k = np.rint((np.asarray(theta, dtype=float) - grid[0]) / (grid[1] - grid[0])).astype(int)
    row = np.full(k.shape, -1)
    for r, d in enumerate(DIRECTIONS):
        row[direction == d] = r
    use = (row >= 0) & (k >= 0) & (k < grid.size) & np.isfinite(f)
    size = len(DIRECTIONS) * grid.size
    bins, values, parity = row[use] * grid.size + k[use], f[use], cycle[use] % 2
    mean = _bin_means(bins, values, size)
    even, odd = parity == 0, parity == 1
    noise = 0.5 * (_bin_means(bins[even], values[even], size) - _bin_means(bins[odd], values[odd], size))
    return mean.reshape(len(DIRECTIONS), grid.size), noise.reshape(len(DIRECTIONS), grid.size)


PAD = 8  # zero-padding factor: a component between two bins still shows as one peak


def _spectrum(curves: list[np.ndarray], step: float) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies (1/degree) and RMS-over-curves amplitude (µm) after a cubic detrend and a
    Hann window, zero-padded ``PAD`` times."""
    n = curves[0].size
    x = np.arange(n) * step
    w = np.hanning(n)
    filled = np.empty((len(curves), n))
    for k, c in enumerate(curves):
        ok = np.isfinite(c)
        filled[k] = np.interp(x, x[ok], c[ok])
    trend = (
        np.polynomial.polynomial.polyvander(x, min(3, n - 1)) @ np.polyfit(x, filled.T, min(3, n - 1))[::-1]
    )
    power = np.sum(np.abs(2.0 * np.fft.rfft((filled - trend.T) * w, PAD * n, axis=1) / w.sum()) ** 2, axis=0)
    return np.fft.rfftfreq(PAD * n, step), np.sqrt(power / len(curves))


def angle_spectrum(
    theta,
    f_ax,
    f_ay,
    direction,
    cycle,
    grid,
    samples_per_period: int = 10,
    significance: float = 4.0,
    min_fraction: float = 0.05,
) -> tuple[AngleSpectrum, np.ndarray]:
    """Spectrum of the swept residuals and the table step it calls for.

    Returns the :class:`AngleSpectrum` and the mean curves, shape (2 axes, 2 directions,
    len(grid)). ``grid`` is the sweep's angles (degree, uniform).
    """
    from scipy.signal import find_peaks  # here: scipy.signal costs every job importing the models ~1 s

    grid = np.asarray(grid, dtype=float)
    s = float(grid[1] - grid[0])
    mx, nx = _curves(theta, f_ax, direction, cycle, grid)
    my, ny = _curves(theta, f_ay, direction, cycle, grid)
    means = [c for c in (*mx, *my) if np.isfinite(c).sum() >= 4]
    noises = [c for c in (*nx, *ny) if np.isfinite(c).sum() >= 4]
    if not means or not noises:
        raise ValueError("angle table: the sweep needs readings at 4 or more angles in 2 or more cycles")
    freq, amp = _spectrum(means, s)
    _, namp = _spectrum(noises, s)
    noise = float(np.sqrt(np.mean(namp[1:] ** 2)))
    peaks, _ = find_peaks(amp)  # the Hann main lobe spreads a component over ±2 bins: count its peak once
    sig = np.zeros(amp.size, dtype=bool)
    sig[peaks] = (amp[peaks] > significance * noise) & (amp[peaks] >= min_fraction * amp[1:].max())
    span = grid[-1] - grid[0]
    if sig.any():
        shortest = float(1.0 / freq[sig].max())
    else:
        shortest = None
    period = shortest if shortest is not None else span
    multiple = max(1, int(np.floor(period / (samples_per_period * s) + 1e-9)))
    step = multiple * s
    nyquist_band = sig & (freq >= 0.8 * freq[-1])
    undersampled = bool(period / s < samples_per_period or nyquist_band.any())
    bound = float(np.sum(amp[sig] * (1 - np.cos(np.pi * step * freq[sig])))) if sig.any() else 0.0
    warning = ""
    if undersampled:
        warning = (
            f"The angle table undersamples the angle-dependent error: its shortest significant period "
            f"is {period:.3g}° and the sweep's {s:.3g}° step gives {period / s:.1f} samples per period "
            f"(wanted {samples_per_period})"
            + (
                "; significant content near the sweep's Nyquist frequency may be aliased"
                if nyquist_band.any()
                else ""
            )
            + ". Sweep with a finer angle_residuals.step_deg."
        )
    with np.errstate(divide="ignore"):
        periods = np.where(freq > 0, 1.0 / np.where(freq > 0, freq, 1.0), np.inf)
    spectrum = AngleSpectrum(s, step, periods, amp, noise, shortest, bound, undersampled, warning)
    return spectrum, np.stack([mx, my])


@dataclass(frozen=True, eq=False)
class AngleTable:
    """f_ax(Θ), f_ay(Θ) (µm) per approach direction of Θ, shape (2, K): forward, backward.

    ``theta`` (degree) are the tabulated angles; α, β (degree) turn f into the joint
    increments g of Eq. (4.19). Between angles, linear interpolation; outside, an error.
    """

    theta: np.ndarray
    f_ax: np.ndarray
    f_ay: np.ndarray
    alpha: float
    beta: float
    info: dict = field(default_factory=dict)

    @classmethod
    def from_sweep(
        cls,
        run: xr.Dataset,
        alpha: float,
        beta: float,
        samples_per_period: int = 10,
        significance: float = 4.0,
        min_fraction: float = 0.05,
    ) -> tuple[AngleTable, AngleSpectrum]:
        """Tabulate the angle characterisation ``run`` (plan ``angle_residuals``, Θ swept)."""
        from calflow.xytheta.evaluation import attained_points

        x, y = attained_points(run)
        v = {
            k: run.variables[k].values
            for k in ("direction", "pose", "target_theta", "target_x", "target_y", "cycle")
        }
        d = v["direction"]
        sel = (v["pose"] > 0) & (d != 0)
        theta = v["target_theta"][sel].astype(float)
        fx = (x - v["target_x"])[sel]
        fy = (y - v["target_y"])[sel]
        # the angle-dependent error is the change of the residual with Θ: at each position,
        # the residual at the lowest swept angle (both directions) is the position's own
        # error, not an angle error (Eq. 4.27: the frame is the home pose's, at Θ = 0)
        where = np.round(v["target_x"][sel], 6) + 1j * np.round(v["target_y"][sel], 6)
        position = np.unique(where, return_inverse=True)[1].ravel()
        ref = np.isclose(theta, np.nanmin(theta)) & np.isfinite(fx) & np.isfinite(fy)
        count = np.bincount(position[ref], minlength=position.max(initial=-1) + 1)
        has_ref = count[position] > 0
        for f in (fx, fy):
            mean = np.bincount(position[ref], weights=f[ref], minlength=count.size) / np.maximum(count, 1)
            f[has_ref] -= mean[position[has_ref]]
        grid_all = np.unique(np.round(theta, 9))
        if grid_all.size < 4:
            raise ValueError(
                f"angle table: run {run.attrs.get('plan')!r} sweeps {grid_all.size} angles, expected 4 or more"
            )
        grid = np.linspace(
            grid_all[0],
            grid_all[-1],
            int(round((grid_all[-1] - grid_all[0]) / np.min(np.diff(grid_all)))) + 1,
        )
        spectrum, curves = angle_spectrum(
            theta, fx, fy, d[sel], v["cycle"][sel], grid, samples_per_period, significance, min_fraction
        )
        every = int(round(spectrum.step_deg / spectrum.sweep_step_deg))
        idx = np.arange(0, grid.size, every)
        if idx[-1] != grid.size - 1:
            idx = np.append(idx, grid.size - 1)
        tx, ty = curves[0][:, idx], curves[1][:, idx]
        for t in (tx, ty):  # a direction with no reading at an angle takes the other's value
            t[0] = np.where(np.isfinite(t[0]), t[0], t[1])
            t[1] = np.where(np.isfinite(t[1]), t[1], t[0])
        if not (np.isfinite(tx).all() and np.isfinite(ty).all()):
            raise ValueError("angle table: some tabulated angle has no valid reading in either direction")
        info = {"sweep_theta": grid, "sweep_f_ax": curves[0], "sweep_f_ay": curves[1]}
        return cls(grid[idx], tx, ty, float(alpha), float(beta), info), spectrum

    def f(self, theta, direction=None) -> tuple[np.ndarray, np.ndarray]:
        """f_ax, f_ay (µm) at angles Θ (degree) approached in ``direction`` (±1; None: the mean)."""
        theta = np.asarray(theta, dtype=float)
        lo, hi = self.theta[0], self.theta[-1]
        if np.any(theta < lo - 1e-9) or np.any(theta > hi + 1e-9):
            raise ValueError(f"angle table: angle outside the table [{lo}, {hi}] degree")
        out = []
        for table in (self.f_ax, self.f_ay):
            fwd, bwd = np.interp(theta, self.theta, table[0]), np.interp(theta, self.theta, table[1])
            if direction is None:
                out.append(0.5 * (fwd + bwd))
            else:
                out.append(np.where(np.asarray(direction) < 0, bwd, fwd))
        return out[0], out[1]

    def g(self, theta, direction=None) -> tuple[np.ndarray, np.ndarray]:
        """Joint increments g_ax, g_ay (µm) cancelling f (Eq. 4.19)."""
        return joint_increments(*self.f(theta, direction), self.alpha, self.beta)

    def to_dataset(self) -> xr.Dataset:
        def var(data, dims, units, long_name):
            return xr.Variable(
                dims, np.asarray(data, dtype=float), attrs={"units": units, "long_name": long_name}
            )

        d = ("direction", "theta")
        data = {
            "f_ax": var(self.f_ax, d, "um", "angle-dependent error along x_WF, f_ax(Θ) (Eq. 4.18)"),
            "f_ay": var(self.f_ay, d, "um", "angle-dependent error along y_WF, f_ay(Θ) (Eq. 4.18)"),
            "alpha": var(self.alpha, (), "degree", "alpha used to compute g"),
            "beta": var(self.beta, (), "degree", "beta used to compute g"),
        }
        coords = {
            "theta": var(self.theta, ("theta",), "degree", "tabulated rotation angle"),
            "direction": xr.Variable(
                ("direction",),
                np.array(DIRECTIONS, dtype="int8"),
                attrs={"units": "1", "long_name": "approach direction of the rotation"},
            ),
        }
        if "sweep_theta" in self.info:
            s = ("direction", "sweep_theta")
            data["sweep_f_ax"] = var(
                self.info["sweep_f_ax"], s, "um", "swept f_ax, mean over positions and cycles"
            )
            data["sweep_f_ay"] = var(
                self.info["sweep_f_ay"], s, "um", "swept f_ay, mean over positions and cycles"
            )
            coords["sweep_theta"] = var(
                self.info["sweep_theta"], ("sweep_theta",), "degree", "swept rotation angle"
            )
        ds = xr.Dataset(data, coords=coords)
        ds.attrs["table"] = "angle_sweep"
        ds.attrs.update({k: v for k, v in self.info.items() if isinstance(v, (int, float, str))})
        return ds

    @classmethod
    def from_dataset(cls, ds: xr.Dataset) -> AngleTable:
        info = {k: v for k, v in ds.attrs.items() if k != "table"}
        if "sweep_theta" in ds:
            info.update(
                sweep_theta=ds["sweep_theta"].values,
                sweep_f_ax=ds["sweep_f_ax"].values,
                sweep_f_ay=ds["sweep_f_ay"].values,
            )
        return cls(*angle_fields(ds), info)
