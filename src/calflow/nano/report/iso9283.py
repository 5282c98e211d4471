"""The ``iso9283`` block of a nano campaign summary: ISO 9283:1998 beyond AP/RP per test type.

Computed from the validation run (lengths in µm in, nm out), per test type (mode), with
the functions of :mod:`calflow.metrics`:

* ``vAP`` (clause 7.3): per test and per target reached from at least two approach
  directions (the run's ``direction``, +1 / −1; 0 = not recorded does not count), the
  largest distance between the direction barycentres; the value is the maximum over the
  mode's tests and targets.  Targets approached from one direction only (the 2-DoF
  validation) give null and say so.
* ``AD`` and ``RD`` (7.4): per test, every pair of poses with different targets, the
  attained positions paired by cycle; ``AD`` is the signed AD of largest magnitude and
  ``RD`` the largest 3 S_D over the pairs and the mode's tests, with the pair's targets.
* ``dAP`` and ``dRP`` (7.7): AP and RP of each pose in the mode's first and last test,
  ``|AP_last − AP_first|`` and ``|RP_last − RP_first|``, maxima over poses; ``period_h``
  is the time between the two tests' mean sample times.
* ``stabilisation_time_s`` (7.5) and ``overshoot`` (7.6) need the record of the approach
  to a pose: they come from the ``step_response`` run (:mod:`calflow.nano.report.stabilisation`),
  whose every move is recorded from its start; they describe the stage's closed loop, which
  no test type changes (a calibration changes the command, not the loop), so every test
  type shows the same entries. Without that run they are null and the ``reason`` says so.

Every entry is ``{"value": number or None, "unit": ..., "clause": ...}`` plus what it was
computed over; a null value always comes with a ``reason``.
"""

from __future__ import annotations

from itertools import combinations

import numpy as np
import xarray as xr

from calflow.metrics import iso9283_distance, iso9283_drift, iso9283_vap
from calflow.nano.evaluation import mode_names, run_columns
from calflow.nano.report.stabilisation import stabilisation_entries

__all__ = ["iso9283_block"]

NM_PER_UM = 1000.0
NO_STREAM = (
    "not supported by this data: no step_response run (the campaign's step_response section is off); "
    "the other runs keep one reading per dwell (the mean of the dwell's last seconds, Sec. 5.3.2), "
    "so no approach to a pose is on record"
)


def _entry(value, unit: str, clause: str, **extra) -> dict:
    out = {"value": None if value is None else float(value), "unit": unit, "clause": clause}
    out.update(extra)
    return out


def _table(meas, cycle, pose, sel):
    """(cycles, poses, d) attained positions of the samples ``sel``; NaN where a visit is missing."""
    cyc, cinv = np.unique(cycle[sel], return_inverse=True)
    pos, pinv = np.unique(pose[sel], return_inverse=True)
    out = np.full((cyc.size, pos.size, meas.shape[1]), np.nan)
    out[cinv, pinv] = meas[sel]
    return out, pos


def _vap(meas, tgt, direction, test, tests):
    best = None
    key = np.round(tgt, 6)
    for t in tests:
        in_t = test == t
        for target in np.unique(key[in_t], axis=0):
            at = in_t & np.all(key == target, axis=1)
            groups = [meas[at & (direction == s)] for s in np.unique(direction[at]) if s != 0]
            if len(groups) < 2:
                continue
            r = iso9283_vap(groups)
            if best is None or r.vap > best[0]:
                best = (r.vap, target, int(t))
    if best is None:
        return _entry(
            None,
            "nm",
            "7.3",
            reason="not supported by this data: no target is approached from two "
            "directions (the run records one approach direction per target)",
        )
    return _entry(
        best[0] * NM_PER_UM,
        "nm",
        "7.3",
        target_um=best[1].tolist(),
        test=best[2],
        over="max over targets and tests",
    )


def _distance(meas, tgt, cycle, pose, test, tests):
    ad = rd = None
    for t in tests:
        sel = test == t
        table, poses = _table(meas, cycle, pose, sel)
        targets = {int(p): tgt[sel & (pose == p)][0] for p in poses}
        for i, j in combinations(range(poses.size), 2):
            c1, c2 = targets[int(poses[i])], targets[int(poses[j])]
            if np.allclose(c1, c2, atol=1e-6):
                continue
            both = np.all(np.isfinite(table[:, i]), axis=1) & np.all(np.isfinite(table[:, j]), axis=1)
            if both.sum() < 2:
                continue
            r = iso9283_distance(c1, c2, table[both, i], table[both, j])
            pair = [c1.tolist(), c2.tolist()]
            if ad is None or abs(r.ad) > abs(ad[0]):
                ad = (r.ad, pair, int(t), r.d_command)
            if rd is None or r.rd > rd[0]:
                rd = (r.rd, pair, int(t), r.d_command)
    if ad is None:
        reason = "not supported by this data: no two poses with different targets share two cycles"
        return {
            "AD": _entry(None, "nm", "7.4.1", reason=reason),
            "RD": _entry(None, "nm", "7.4.2", reason=reason),
        }
    over = "pair of poses and test with the largest value"
    return {
        key: _entry(
            value * NM_PER_UM,
            "nm",
            clause,
            pair_targets_um=pair,
            test=test,
            command_distance_um=distance,
            over=o,
        )
        for key, (value, pair, test, distance), clause, o in (
            ("AD", ad, "7.4.1", over + " in magnitude (signed)"),
            ("RD", rd, "7.4.2", over),
        )
    }


def _drift(meas, tgt, pose, test, tests, hours):
    if tests.size < 2:
        reason = "not supported by this data: the test type has one test; drift compares a first and a last"
        return {
            "dAP": _entry(None, "nm", "7.7", reason=reason),
            "dRP": _entry(None, "nm", "7.7", reason=reason),
        }
    first, last = int(tests[0]), int(tests[-1])
    dap = drp = None
    for p in np.unique(pose[test == first]):
        a, b = (test == first) & (pose == p), (test == last) & (pose == p)
        if a.sum() < 2 or b.sum() < 2:
            continue
        r = iso9283_drift(tgt[a][0], meas[a], meas[b])
        if dap is None or r.dap > dap[0]:
            dap = (r.dap, tgt[a][0].tolist())
        if drp is None or r.drp > drp[0]:
            drp = (r.drp, tgt[a][0].tolist())
    period = float(hours[test == last].mean() - hours[test == first].mean())
    span = {"first_test": first, "last_test": last, "period_h": period, "over": "max over poses"}
    if dap is None:
        reason = (
            "not supported by this data: no pose has two valid visits in both the first and the last test"
        )
        return {
            "dAP": _entry(None, "nm", "7.7", reason=reason),
            "dRP": _entry(None, "nm", "7.7", reason=reason),
        }
    return {
        "dAP": _entry(dap[0] * NM_PER_UM, "nm", "7.7", target_um=dap[1], **span),
        "dRP": _entry(drp[0] * NM_PER_UM, "nm", "7.7", target_um=drp[1], **span),
    }


def iso9283_block(run: xr.Dataset, step_response_run: xr.Dataset | None = None) -> dict:
    """ISO 9283 vAP, AD, RD, dAP, dRP per test type of a nano validation run, and the
    stabilisation time and overshoot of the ``step_response_run`` (see the module docstring);
    JSON-ready except for numpy scalars."""
    axes = [a for a in ("x", "y") if f"target_{a}" in run]
    columns = run_columns(run, axes)
    valid = np.all(np.isfinite(columns[0]), axis=1) & np.all(np.isfinite(columns[1]), axis=1)
    meas, tgt, pose, cycle, direction, test, mode, hours = (v[valid] for v in columns)
    if step_response_run is not None:
        stab, overshoot = stabilisation_entries(step_response_run)
    else:
        stab, overshoot = (
            _entry(None, "s", "7.5", reason=NO_STREAM),
            _entry(None, "nm", "7.6", reason=NO_STREAM),
        )
    modes = {}
    for k, name in enumerate(mode_names(run)):
        tests = np.unique(test[mode == k])
        if tests.size == 0:
            continue
        modes[name] = {
            "vAP": _vap(meas, tgt, direction, test, tests),
            **_distance(meas, tgt, cycle, pose, test, tests),
            **_drift(meas, tgt, pose, test, tests, hours),
            "stabilisation_time_s": dict(stab),
            "overshoot": dict(overshoot),
        }
    return {
        "standard": "ISO 9283:1998",
        "source": f"{run.attrs.get('plan', 'validation')} run",
        "axes": axes,
        "modes": modes,
    }
