"""Error budget after calibration of the simulated nano rigs, per effect.

For the summary step only (like the truth blocks): it reads the simulated rig's truth,
which analysis never does. Lengths in nm in the result.

Method. Every deterministic effect e of the rig (:data:`calflow.nano.stage.options.EFFECTS`)
is evaluated with and without it at the recorded samples of the training and validation
runs — same commands, same times, same history of moves (hysteresis states, last step for
creep) — which gives its term d_e (um) at each sample. A calibration model fitted by least
squares to training data that contain d_e compensates the part of d_e its regressors can
represent, and the least-squares fit is linear in the data, so what is left of e at a
validation sample is

    u_e = d_e(validation) - P[d_e](validation)

with P the projection fitted on the training samples onto the model's regressors:
no calibration: none (u_e = d_e); single, Eq. (5.3) and 2-DoF, Eq. (5.10): the position
polynomial of the model's order (in the measured positions) plus the four thermocouple
readings plus a constant; adaptive KMZ, Eq. (5.6): the single model's polynomial plus the
offset the kilometre-zero visit of the test measured (d_e - P at the visit). The budget of
a test type is the rms of each u_e over its samples at the held-out positions (those
training never visited); ``noise_and_estimation`` is the rms of what the effects do not
explain (measured error minus the sum of the u_e: noise, per-move repeatability, the
models' estimation error); ``total`` the rms of the measured error; ``interaction`` the
signed root of total^2 - (sum of squares of the others): the correlation between
contributions, positive when they add up, negative when they partly cancel.

The thermocouples' own errors (calibration drift, reference junction, a junction lagging
its part; :data:`calflow.nano.stage.unseen.options.TC_ERRORS`) err the regressors, not the
position: a model reads them and compensates a drift that is not there. Their entry is the
rms of the change of what the model leaves when that error is taken out of the readings,
training and validation alike (zero for no calibration and, the thermocouples aside from its
fit, nearly so for KMZ). They are inside the other entries, so they are left out of
``noise_and_estimation`` and ``interaction``.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from calflow.nano.evaluation import run_seconds
from calflow.nano.stage.options import EFFECTS, NOISE
from calflow.nano.stage.unseen.options import TC_ERRORS
from calflow.rigs.simulated.budget import signed_root

__all__ = ["rig_from_truth", "effect_samples", "error_budget"]

DETERMINISTIC = tuple(e for e in EFFECTS if e not in NOISE and e not in TC_ERRORS)


def rig_from_truth(truth: dict):
    """A fresh simulated nano rig with the physics of a ``truth`` dict (``rig.truth()``)."""
    from calflow.nano.stage.rig import nano1d, nano2d

    o = dict(truth["options"])
    room = truth["room"]
    o.update(
        profile=room["name"],
        profile_params=dict(room["params"]),
        world_seed=truth.get("world_seed", room["seed"]),
    )
    return {"nano1d": nano1d, "nano2d": nano2d}[truth["rig"]](**o)


def _seconds(run: xr.Dataset, name: str) -> np.ndarray:
    return run_seconds(
        run if name == "time" else run.rename({name: "time"}).drop_dims("sample", errors="ignore")
    )


def effect_samples(rig, run: xr.Dataset, since_s: float, visits: dict | None = None) -> dict:
    """Each deterministic effect's term (um, (n_samples, n_axes)) at the samples of ``run``,
    replaying its commands in order from rest at 0 (and a visit command before sample i for each
    ``visits[i] = (time_s, command_um)``); ``since_s`` is the time from a move's start to its
    reading. Returns ``{"samples": {effect: array}, "visits": {effect: (n_visits, n_axes)},
    "thermocouples": {error: (n_samples, n_tc) K}}`` (the thermocouples' own errors)."""
    joints = rig.joints
    cmd = np.column_stack([run[f"cmd_{j}"].values for j in joints])
    t = run_seconds(run)
    visits = visits or {}
    rows, times, is_visit = [], [], []
    for i in range(len(t)):
        if i in visits:
            tv, qv = visits[i]
            rows.append([qv] + list(cmd[i, 1:]))
            times.append(tv)
            is_visit.append(True)
        rows.append(list(cmd[i]))
        times.append(t[i])
        is_visit.append(False)
    q = np.array(rows, dtype=float)
    steps = np.diff(np.vstack([np.zeros((1, len(joints))), q]), axis=0)
    z = tuple(rig.play.sequence(q[:, k]) for k in range(len(joints)))
    times = np.array(times, dtype=float)
    terms = rig.effect_terms(
        tuple(q[:, k] for k in range(len(joints))),
        times,
        z,
        tuple(steps[:, k] for k in range(len(joints))),
        np.full(len(times), since_s),
        memory=rig._unseen.replay(times - since_s, steps),
    )
    axes = [k for k, a in enumerate(rig._AXIS) if a is not None]
    v = np.array(is_visit)
    out = {e: np.column_stack([np.asarray(terms[e][k], dtype=float) for k in axes]) for e in DETERMINISTIC}
    tc = rig._unseen.thermocouples(times + rig.options["start_offset_s"])
    return {
        "samples": {e: a[~v] for e, a in out.items()},
        "visits": {e: a[v] for e, a in out.items()},
        "thermocouples": {e: tc[e][~v] for e in TC_ERRORS},
    }


def _design(pos: np.ndarray, temps: np.ndarray, order: int, stroke: float) -> tuple[np.ndarray, int]:
    """Regressors: 1, powers 1..order of each position column (/stroke), thermocouples (- 20 degC).
    Returns (matrix, index after the polynomial columns)."""
    cols = [np.ones(len(pos))]
    for k in range(pos.shape[1]):
        cols += [(pos[:, k] / stroke) ** i for i in range(1, order + 1)]
    n_poly = len(cols)
    cols += [temps[:, j] - 20.0 for j in range(temps.shape[1])]
    return np.column_stack(cols), n_poly


def error_budget(truth: dict, campaign: dict, training: xr.Dataset, validation: xr.Dataset) -> dict:
    """``{mode: {effect: nm, ..., noise_and_estimation, interaction, total}}`` at the held-out
    validation positions (module docstring), plus ``"method"``: how contributions combine."""
    rig = rig_from_truth(truth)
    joints = rig.joints
    rise = rig.options["rise_time_s"]
    order = int(campaign.get("model", {}).get("order", 3))

    def since(run, section):
        avg = campaign.get(section, {}).get("average_last_s")
        return rise + float(run.attrs.get("dwell_s", 0.0)) - (0.5 * avg if avg else 0.0)

    modes = str(validation["test_mode"].attrs.get("flag_meanings", "")).split()
    mode = validation["test_mode"].values
    test = validation["test"].values
    visits = {}
    if "kmz_time" in validation:
        kmz = modes.index("adaptive_kmz") if "adaptive_kmz" in modes else -1
        first = [i for i in range(len(test)) if mode[i] == kmz and (i == 0 or test[i] != test[i - 1])]
        tk = _kmz_seconds(validation)
        visits = {i: (tk[n], float(validation["kmz_command"].values[n])) for n, i in enumerate(first)}
    d_train = effect_samples(rig, training, since(training, "training"))
    d_val = effect_samples(rig, validation, since(validation, "validation"), visits)
    pos_tr = np.column_stack([training[f"meas_{j}"].values for j in joints])
    tgt = np.column_stack([validation[f"target_{j}"].values for j in joints])
    train_targets = np.column_stack([training[f"target_{j}"].values for j in joints])
    held = ~np.array([np.any(np.all(np.abs(train_targets - v) < 1e-6, axis=1)) for v in tgt])
    err = np.column_stack([validation[f"meas_{j}"].values for j in joints]) - tgt
    stroke = rig.options["stroke_um"]
    X_tr, n_poly = _design(pos_tr, training["temperature"].values, order, stroke)
    ok = np.all(np.isfinite(X_tr), axis=1)
    X_val, _ = _design(tgt, validation["temperature"].values, order, stroke)
    d_tr_all = sum(d_train["samples"][e] for e in DETERMINISTIC)
    d_val_all = sum(d_val["samples"][e] for e in DETERMINISTIC)
    d_vis_all = sum(d_val["visits"][e] for e in DETERMINISTIC)
    n_poly_val = n_poly

    def corrected(X, eps):  # the regressors without a thermocouple error
        X = X.copy()
        X[:, n_poly_val:] -= eps
        return X

    fit = _Fit(visits, test, joints, order, stroke, n_poly)
    out = {}
    for k, name in enumerate(modes):
        rows = held & (mode == k)
        if not rows.any():
            continue
        u = {
            e: fit.left(name, d_train["samples"][e], d_val["samples"][e], d_val["visits"][e], X_tr, X_val, ok)
            for e in DETERMINISTIC
        }
        both = fit.left(name, d_tr_all, d_val_all, d_vis_all, X_tr, X_val, ok)
        tc = {}
        for e in TC_ERRORS:
            Xt = corrected(X_tr, d_train["thermocouples"][e])
            Xv = corrected(X_val, d_val["thermocouples"][e])
            tc[e] = both - fit.left(name, d_tr_all, d_val_all, d_vis_all, Xt, Xv, ok)
        out[name] = _combine({e: v[rows] for e, v in u.items()}, err[rows])
        out[name].update({e: _rms(v[rows][np.all(np.isfinite(err[rows]), axis=1)]) for e, v in tc.items()})
    out["method"] = (
        "rms over the samples at held-out validation positions of each effect's term left after the "
        "model's least-squares compensation (fitted on the training samples); noise_and_estimation = "
        "rms of the measured error minus the sum of those terms; interaction = signed root of "
        "total^2 minus the sum of the squares of all the others (contributions combine as the root-sum-"
        "square when uncorrelated)"
    )
    return out


class _Fit:
    """What a model leaves of a term (um): ``left(mode, d_train, d_val, d_visits, X_tr, X_val, ok)``
    (module docstring), for one validation run's KMZ visits."""

    def __init__(self, visits, test, joints, order, stroke, n_poly):
        self.order, self.stroke, self.n_poly, self.n_joints = order, stroke, n_poly, len(joints)
        keys = np.array(sorted(visits))
        self.xk = np.array([visits[i][1] for i in sorted(visits)])[:, None]
        self.which = np.clip(np.searchsorted(keys, np.arange(len(test)), side="right") - 1, 0, None)

    def left(self, name, d_tr, d_val, d_vis, X_tr, X_val, ok):
        if name == "no_calibration":
            return d_val
        coef, *_ = np.linalg.lstsq(X_tr[ok], d_tr[ok], rcond=None)
        if name != "adaptive_kmz":
            return d_val - X_val @ coef
        geo = coef.copy()
        geo[0] = 0.0
        geo[self.n_poly :] = 0.0
        xk = self.xk
        Xk, _ = _design(
            np.column_stack([xk] + [np.zeros_like(xk)] * (self.n_joints - 1)),
            np.zeros((len(xk), X_val.shape[1] - self.n_poly)),
            self.order,
            self.stroke,
        )
        offset_k = d_vis - Xk @ geo  # what the visit measures and removes
        return d_val - X_val @ geo - offset_k[self.which]


def _kmz_seconds(run: xr.Dataset) -> np.ndarray:
    v = run["kmz_time"]
    fake = xr.Dataset({"time": (("sample",), v.values)})
    fake["time"].encoding.update(v.encoding)
    fake.attrs.update(run.attrs)
    return run_seconds(fake)


def _rms(a: np.ndarray) -> float:
    a = a[np.all(np.isfinite(a), axis=1)] if a.ndim == 2 else a
    return float(np.sqrt(np.mean(np.sum(a * a, axis=-1)))) * 1e3 if a.size else float("nan")


def _combine(u: dict, err: np.ndarray) -> dict:
    """Contributions (nm) of each effect, the unexplained remainder, the total and the interaction."""
    good = np.all(np.isfinite(err), axis=1)
    out = {e: _rms(v[good]) for e, v in u.items()}
    rest = err[good] - sum(v[good] for v in u.values())
    out["noise_and_estimation"] = _rms(rest)
    total = _rms(err[good])
    ss = sum(c * c for c in out.values())
    out["interaction"] = signed_root(total**2 - ss)
    out["total"] = total
    return out


def humidity_ranges(truth: dict, training: xr.Dataset, metrics: xr.Dataset) -> dict:
    """The simulated room's relative humidity (%RH) over the training run and over each test of
    a validation metrics dataset (``time_start_h``/``time_end_h``, campaign hours), for the
    report's extrapolation sentences (:mod:`calflow.nano.report.extrapolation`); on a 10 min grid."""
    rig = rig_from_truth(truth)
    t = run_seconds(training)
    grid = np.arange(np.nanmin(t), np.nanmax(t) + 600.0, 600.0)
    train = rig._weather_at(grid)[1]
    tests = []
    for a, b in zip(metrics["time_start_h"].values * 3600.0, metrics["time_end_h"].values * 3600.0):
        rh = rig._weather_at(np.append(np.arange(a, b, 600.0), b))[1]
        tests.append([float(rh.min()), float(rh.max())])
    return {"training_pct": [float(train.min()), float(train.max())], "tests_pct": tests}
