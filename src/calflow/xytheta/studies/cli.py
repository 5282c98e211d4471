"""``calflow mc-point``, ``mc-aggregate``, ``mc-report``: the Monte-Carlo study of the XYΘ
identification (:mod:`calflow.xytheta.studies.montecarlo`), one point per job, then the aggregate and its page."""

from __future__ import annotations

import json
import math
from pathlib import Path

from calflow.errors import CalflowError


def _study(args) -> dict:
    from calflow.xytheta.studies.montecarlo import load_study

    return load_study(args.study, args.campaign_dir)


def point(args) -> None:
    """One point of the study's grid (seed × noise × poses), or a batch of seeds ``A-B``."""
    from calflow.acquisition.progress import progress
    from calflow.data.io import write_json
    from calflow.xytheta.studies.montecarlo import noise_label, parse_seeds, run_point

    s = _study(args)
    noise = float(args.noise)
    seeds = parse_seeds(args.seed)
    if seeds[0] < 0 or seeds[-1] >= s["seeds"]:
        raise CalflowError(
            f"{args.study}: --seed {args.seed}: expected seeds 0 .. {s['seeds'] - 1} (key 'seeds')"
        )
    if not any(math.isclose(noise, n) for n in s["noise_um"]) and not args.off_grid:
        raise CalflowError(
            f"{args.study}: --noise {noise_label(noise)}: not in key 'noise_um' {s['noise_um']}"
        )
    if args.poses not in s["poses"] and not args.off_grid:
        raise CalflowError(f"{args.study}: --poses {args.poses}: not in key 'poses' {s['poses']}")
    points = []
    with progress(f"{s['name']} noise {noise_label(noise)} um, {args.poses} poses", len(seeds)) as step:
        for seed in seeds:
            points.append(
                run_point(
                    s["base"],
                    seed,
                    noise,
                    args.poses,
                    model=s["model"],
                    validation_cycles=s["validation_cycles"],
                    rig_options=s["rig_options"],
                )
            )
            step(len(points), len(seeds))
    write_json({"study": s["name"], "points": points}, args.out)


def _points(path: str) -> list[dict]:
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise CalflowError(f"{path}: not a point file ({exc})") from None
    if not isinstance(data, dict) or not isinstance(data.get("points", {}), list):
        raise CalflowError(f"{path}: not a point file (expected a mapping with 'points')")
    return data["points"] if "points" in data else [data]


def aggregate(args) -> None:
    """Statistics per noise × poses over all points; every grid point must be there."""
    from calflow.data.io import write_json
    from calflow.xytheta.studies.aggregate import aggregate as combine
    from calflow.xytheta.studies.montecarlo import grid, noise_label

    s = _study(args)
    points = [p for path in args.points for p in _points(path)]
    have = {(p["seed"], noise_label(p["noise_um"]), p["poses"]) for p in points}
    if len(have) != len(points):
        raise CalflowError(
            f"{args.study}: some grid points are given twice ({len(points)} points, {len(have)} distinct)"
        )
    missing = [g for g in grid(s) if g not in have]
    if missing and not args.partial:
        seed, noise, poses = missing[0]
        raise CalflowError(
            f"{args.study}: {len(missing)} grid point(s) missing, e.g. seed {seed}, "
            f"noise {noise} um, {poses} poses (pass every point file, or --partial)"
        )
    agg = combine(points)
    agg.update(study=s["name"], missing=len(missing), grid={k: s[k] for k in ("seeds", "noise_um", "poses")})
    write_json(agg, args.out)


def page(args) -> None:
    """The study's HTML report page."""
    from calflow.data.io import write_text
    from calflow.xytheta.studies.montecarlo import render_page

    s = _study(args)
    write_text(render_page(json.loads(Path(args.aggregate).read_text()), s), args.out)
