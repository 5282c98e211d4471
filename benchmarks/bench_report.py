"""Time the rendering of campaign reports as ``calflow report`` does: the HTML with inline SVG
figures and its print page with the same figures as PNG (one drawing of each figure), then
the PDF of the print page.

Usage::

    .venv/bin/python benchmarks/bench_report.py RUN_DIR [--campaign NAME ...] [--repeat N] [--out DIR]

``RUN_DIR`` is a finished run: ``results/<campaign>/summary.json`` beside the campaign's
result files, and ``config/campaigns/<campaign>.yaml``.  By default the three thesis
campaigns (``xytheta-thesis``, ``nano1d-thesis``, ``nano2d-thesis``) are timed.  The
report inputs are the files the report rule passes (the summary's ``inputs``) plus, for
XYΘ, ``runs/identification.nc`` when present.  Outputs go to ``--out`` (a temporary
directory by default); ``RUN_DIR`` is only read.  Prints seconds per campaign for the HTML
and the PDF (best of ``--repeat``) and the machine.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

THESIS = ("xytheta-thesis", "nano1d-thesis", "nano2d-thesis")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run_dir", type=Path)
    p.add_argument(
        "--campaign", action="append", help="campaign name (repeatable); default: the thesis campaigns"
    )
    p.add_argument("--repeat", type=int, default=1)
    p.add_argument("--out", type=Path)
    p.add_argument("--smoke", action="store_true", help="one repeat of nano2d-thesis's pages only, for CI")
    args = p.parse_args(argv)
    if args.smoke:
        args.repeat, args.campaign = 1, args.campaign or ["nano2d-thesis"]

    t0 = time.perf_counter()
    import matplotlib  # noqa: F401  (import costs are reported separately)

    from calflow.configuration.campaign import load as load_campaign
    from calflow.report.render import render_campaign_pages, write_pdf

    import_s = time.perf_counter() - t0
    run_dir = args.run_dir.resolve()
    out = (args.out or Path(tempfile.mkdtemp(prefix="calflow-bench-report-"))).resolve()
    out.mkdir(parents=True, exist_ok=True)
    cwd = os.getcwd()
    os.chdir(run_dir)  # the summaries name their inputs relative to the run directory
    print(
        f"machine: {platform.platform()} {platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}; {platform.processor() or 'cpu n/a'}"
    )
    print(
        f"imports (calflow.configuration.config, calflow.report, matplotlib): {import_s:.2f} s; the figure modules load in the first HTML"
    )
    print(f"{'campaign':<18} {'HTML (s)':>9} {'PDF (s)':>9} {'total (s)':>10} {'HTML kB':>8} {'pages':>6}")
    total = 0.0
    try:
        for name in args.campaign or THESIS:
            summary_path = Path("results") / name / "summary.json"
            if not summary_path.exists():
                print(f"{name:<18} (no {summary_path})")
                continue
            summary = json.loads(summary_path.read_text())
            campaign = load_campaign(Path("config/campaigns") / f"{name}.yaml")
            files = list(summary.get("inputs", {}))
            ident = Path("results") / name / "runs/identification.nc"
            if summary["robot"] == "xytheta" and ident.exists():
                files.append(str(ident))
            command = f"snakemake --cores 2 --config 'campaigns=[\"{name}\"]'"
            best_html = best_pdf = float("inf")
            for _ in range(max(1, args.repeat)):
                a = time.perf_counter()
                html, printed = render_campaign_pages(summary, campaign, command, files)
                b = time.perf_counter()
                pdf = write_pdf(printed, out)
                c = time.perf_counter()
                best_html, best_pdf = min(best_html, b - a), min(best_pdf, c - b)
            (out / f"{name}.html").write_text(html)
            (out / f"{name}.pdf").write_bytes(pdf)
            pages = _pages(pdf)
            total += best_html + best_pdf
            print(
                f"{name:<18} {best_html:>9.2f} {best_pdf:>9.2f} {best_html + best_pdf:>10.2f} "
                f"{len(html) / 1e3:>8.0f} {pages:>6}"
            )
    finally:
        os.chdir(cwd)
    print(f"all campaigns: {total:.2f} s; outputs in {out}")
    return 0


def _pages(pdf: bytes) -> int:
    import re
    import zlib

    chunks = [pdf]
    for m in re.finditer(rb"stream\r?\n", pdf):
        try:
            chunks.append(zlib.decompressobj().decompress(pdf[m.end() :]))
        except zlib.error:
            pass
    return sum(len(re.findall(rb"/Type\s*/Page(?![a-zA-Z])", c)) for c in chunks)


if __name__ == "__main__":
    sys.exit(main())
