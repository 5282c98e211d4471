"""Design study of the XYΘ identification: how many poses and how much rig time
for the σ the user asks for, random against designed.

From the Fisher information alone (no acquisition): for a range of pose counts, the
Cramér–Rao σ of every parameter of ``identification.design.model`` and the virtual rig
time, for the random plan (the campaign's own draw, in its drawn order) and for the
designed plan (:mod:`calflow.xytheta.design.plan`, ordered). For ``design_study.sigma_target``
it answers the poses and hours each plan needs where its curve crosses the target, or
beyond the largest count by σ ∝ 1/√n (a plan of the same shape with more poses).
"""

from __future__ import annotations

import json

import numpy as np

from calflow.xytheta.design import criteria as design
from calflow.xytheta.design import plan as dp

PLANS = ("random", "designed")


def curves(campaign: dict, counts) -> dict:
    """σ (plan, count, parameter) in µm/degree and rig time (plan, count) in h, with the parameter keys."""
    p, d = campaign["identification"], campaign["identification"]["design"]
    noise, tm = dp.noise_model(campaign), dp.time_model(campaign)
    phi, free = dp._phi(campaign, d["model"])
    lo = np.array([p["x_um"][0], p["y_um"][0], p["theta_deg"][0]], dtype=float)
    hi = np.array([p["x_um"][1], p["y_um"][1], p["theta_deg"][1]], dtype=float)
    pool = dp.candidates(int(d["candidates"]), p["x_um"], p["y_um"], p["theta_deg"], campaign["seed"])
    base = "MV" if d["criterion"] == "discrepancy" else d["criterion"]  # its polish keeps the MV design's σ
    ref = design.crlb_sigma(
        design.pose_jacobians(dp._random_poses(campaign, p["poses"]), phi, free), noise.sigma(1)
    )
    sigma = np.full((2, len(counts), len(free)), np.nan)
    hours = np.full((2, len(counts)), np.nan)
    home = np.zeros((1, 3))
    for k, n in enumerate(counts):
        rq = dp._random_poses(campaign, n - 1)
        poses = dp.design_poses(min(n - 1, len(pool)), pool, phi, free, base, ref, d["space_filling"], lo, hi)
        dq = np.vstack([home, poses[dp.order(poses, tm)]])
        for j, q in enumerate((rq, dq)):
            sigma[j, k] = design.crlb_sigma(design.pose_jacobians(q, phi, free), noise.sigma(1))
            hours[j, k] = tm.plan_s(q) / 3600.0
    return {"sigma": sigma, "rig_time_h": hours, "parameters": [design.parameter_key(f) for f in free]}


def needed(counts, sigma: np.ndarray, hours: np.ndarray, parameters: list[str], target: dict) -> dict:
    """Poses and rig time (h) each plan needs for every targeted σ: where its curve of the worst
    ratio σ/target crosses 1 (log-log interpolation between counts), or beyond the largest count
    scaled by σ ∝ 1/√n. Targets of parameters the model does not identify are ignored."""
    keys = [k for k in target if k in parameters]
    counts = np.asarray(counts, dtype=float)
    out = {}
    for j, name in enumerate(PLANS):
        if not keys:
            out[name] = {"poses": None, "rig_time_h": None}
            continue
        ratio = np.max([sigma[j, :, parameters.index(k)] / float(target[k]) for k in keys], axis=0)
        met = np.flatnonzero(ratio <= 1.0)
        if met.size == 0:
            n = counts[-1] * ratio[-1] ** 2
            h = hours[j, -1] / counts[-1] * n
        elif met[0] == 0:
            n, h = counts[0], hours[j, 0]
        else:
            k = met[0]
            u = np.log(ratio[k - 1]) / (np.log(ratio[k - 1]) - np.log(ratio[k]))  # where log ratio = 0
            n = float(np.exp(np.log(counts[k - 1]) + u * (np.log(counts[k]) - np.log(counts[k - 1]))))
            h = float(np.exp(np.log(hours[j, k - 1]) + u * (np.log(hours[j, k]) - np.log(hours[j, k - 1]))))
        out[name] = {"poses": int(np.ceil(n)), "rig_time_h": float(h)}
    return out


def study(args) -> None:
    """``calflow design-study``: the study's curves and answer as a metrics dataset."""
    import xarray as xr

    from calflow.commands.common import campaign_of, meta
    from calflow.data.io import write_dataset

    c = campaign_of(args)
    s = c["design_study"]
    counts = np.unique(np.geomspace(s["min_poses"], s["max_poses"], s["steps"]).round().astype(int))
    r = curves(c, counts)
    answer = needed(counts, r["sigma"], r["rig_time_h"], r["parameters"], s.get("sigma_target") or {})
    units = {k: "degree" if k.endswith("_deg") else "um" for k in r["parameters"]}
    ds = xr.Dataset(
        {
            "sigma": xr.Variable(
                ("plan", "poses", "parameter"),
                r["sigma"],
                attrs={
                    "units": "1",
                    "long_name": "Cramér–Rao sigma (parameter units: attribute units_by_parameter)",
                },
            ),
            "rig_time_h": xr.Variable(
                ("plan", "poses"), r["rig_time_h"], attrs={"units": "h", "long_name": "virtual rig time"}
            ),
        },
        coords={
            "plan": xr.Variable(("plan",), np.array(PLANS, dtype=object)),
            "poses": xr.Variable(
                ("poses",), counts, attrs={"units": "1", "long_name": "poses (home included)"}
            ),
            "parameter": xr.Variable(("parameter",), np.array(r["parameters"], dtype=object)),
        },
        attrs=meta(c, "simulated", "design_study").attrs("metrics"),
    )
    ds.attrs.update(
        units_by_parameter=json.dumps(units),
        sigma_target=json.dumps(s.get("sigma_target") or {}),
        needed=json.dumps(answer),
        model=c["identification"]["design"]["model"],
        criterion=c["identification"]["design"]["criterion"],
    )
    write_dataset(ds, args.out)


def summary_block(ds) -> dict:
    """The study as the summary's ``design_study`` block."""
    return {
        "model": ds.attrs.get("model"),
        "criterion": ds.attrs.get("criterion"),
        "poses": [int(v) for v in ds["poses"].values],
        "parameters": [str(v) for v in ds["parameter"].values],
        "sigma": {str(p): [[float(v) for v in row] for row in ds["sigma"].sel(plan=p).values] for p in PLANS},
        "rig_time_h": {str(p): [float(v) for v in ds["rig_time_h"].sel(plan=p).values] for p in PLANS},
        "sigma_target": json.loads(ds.attrs.get("sigma_target", "{}")),
        "needed": json.loads(ds.attrs.get("needed", "{}")),
    }


def figure(summary: dict):
    """σ against poses and against rig time, random and designed, each parameter relative to its
    target (or, without one, to the random plan's σ at the largest count) — report figure."""
    from calflow.report.figures import COLORS, finish, new_figure

    s = summary.get("design_study")
    if not s or not s.get("poses"):
        return None
    fig, ax = new_figure(2, height=2.6)
    target = s.get("sigma_target") or {}
    colors = [COLORS[m] for m in ("II", "III", "IV", "V")]
    for j, k in enumerate(s["parameters"]):
        ref = float(target.get(k, np.array(s["sigma"]["random"], dtype=float)[-1, j]))
        for plan, style in (("random", "--"), ("designed", "-")):
            sig = np.array(s["sigma"][plan], dtype=float)[:, j] / ref
            label = f"{k}, {plan}"
            ax[0, 0].loglog(
                s["poses"], sig, style, marker="o", ms=2, lw=0.9, color=colors[j % 4], label=label
            )
            ax[0, 1].loglog(s["rig_time_h"][plan], sig, style, marker="o", ms=2, lw=0.9, color=colors[j % 4])
    for a, xlabel in zip(ax[0], ("poses", "virtual rig time (h)")):
        a.axhline(1.0, color=COLORS["thesis"], lw=0.8)
        a.set_xlabel(xlabel)
        a.set_ylabel("CRLB σ / σ asked" if target else "CRLB σ / random σ at most poses")
    ax[0, 0].legend(loc="lower left", fontsize="x-small", ncol=2)
    need = s.get("needed") or {}
    answer = "; ".join(
        f"{plan}: {v['poses']} poses, {v['rig_time_h']:.2f} h"
        for plan, v in need.items()
        if v.get("poses") is not None
    )
    caption = (
        f"Design study: Cramér–Rao σ of Model {s['model']}'s parameters against the number of poses (a) "
        f"and the virtual rig time (b), random poses (dashed) against the {s['criterion']}-optimal design "
        "(solid), from the Fisher information under the sensor's noise model (no acquisition); each "
        + (
            "parameter relative to the σ asked (design_study.sigma_target; unasked ones to the random plan's "
            "σ at the most poses)"
            if target
            else "parameter relative to the random plan's σ at the most poses"
        )
    )
    caption += f". For the σ asked: {answer}." if answer else "."
    return finish(fig, "fig-design-study", "identification", caption, "Fig. 4.21")
