#!/usr/bin/env python
"""Compare two default runs' summary.json files: every figure outside the Monte Carlo records
(``uncertainty``, ``conformity``, ``certificate``) must be byte-identical; each Monte Carlo U
and interval end is set beside its old value and the new record's numerical tolerance δ
(JCGM 101 §7.9, docs/certificate.md), "within" or "OUTSIDE".

    .venv/bin/python benchmarks/compare_summaries.py OLD_RESULTS NEW_RESULTS
    .venv/bin/python benchmarks/compare_summaries.py --smoke RESULTS   # a run against itself (CI)

Exits 1 if a figure outside the Monte Carlo records differs.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import sys

MC = {"uncertainty", "conformity", "certificate"}


def walk(a, b, path, diffs, mc):
    """Differences of ``a`` and ``b`` outside the Monte Carlo keys (``diffs``) and the pairs of
    Monte Carlo records (``mc``)."""
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            p = path + [k]
            if k not in a or k not in b:
                diffs.append((p, "only in " + ("new" if k in b else "old")))
            elif k == "uncertainty" and isinstance(a[k], dict) and isinstance(b[k], dict):
                mc.extend((p + [f], a[k].get(f), b[k].get(f)) for f in sorted(set(a[k]) | set(b[k])))
            elif k in MC:
                if a[k] != b[k]:
                    mc.append((p, a[k], b[k]))
            else:
                walk(a[k], b[k], p, diffs, mc)
    elif isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b)):
            walk(x, y, path + [i], diffs, mc)
    elif a != b:
        diffs.append((path, f"{a!r} -> {b!r}"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old")
    ap.add_argument("new", nargs="?")
    ap.add_argument("--smoke", action="store_true", help="compare a run with itself (CI)")
    a = ap.parse_args(argv)
    new = a.old if a.smoke or a.new is None else a.new
    changed = 0
    for f in sorted(glob.glob(f"{new}/*/summary.json")):
        name = f.split("/")[-2]
        old_file = f"{a.old}/{name}/summary.json"
        if not os.path.exists(old_file):
            print(f"== {name}: no old summary")
            continue
        diffs, mc = [], []
        walk(json.load(open(old_file)), json.load(open(f)), [], diffs, mc)
        changed += len(diffs)
        print(f"== {name}: {len(diffs)} non-Monte-Carlo differences")
        for p, d in diffs[:20]:
            print("   ", ".".join(map(str, p)), d[:200])
        for p, x, y in mc:
            if not (isinstance(x, dict) and isinstance(y, dict) and "U" in x and "U" in y):
                continue
            tol = (y.get("monte_carlo") or {}).get("tolerance")
            worst = max(abs(y["U"] - x["U"]), *(abs(v - w) for v, w in zip(y["interval"], x["interval"])))
            verdict = "" if tol is None else ("within" if worst <= tol else "OUTSIDE")
            print(
                f"   {'.'.join(map(str, p))}: U {x['U']:.4g} -> {y['U']:.4g}; interval "
                f"[{x['interval'][0]:.4g}, {x['interval'][1]:.4g}] -> [{y['interval'][0]:.4g}, "
                f"{y['interval'][1]:.4g}]; tol {tol}; {verdict}"
            )
    return 1 if changed else 0


if __name__ == "__main__":
    sys.exit(main())
