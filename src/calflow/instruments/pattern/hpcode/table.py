"""HP-code markers as ``calflow decode`` writes them: one CSV row per marker found (or per
frame with none), in calflow's convention or as the Vernier library prints a marker's pose."""

from __future__ import annotations

import csv
import io
import math

from calflow.instruments.pattern.hpcode.decode import FIELDS, Markers


def markers_csv(found: Markers, origin, convention: str = "calflow") -> str:
    """The CSV text: ``file, page, number``, the pose (``x_um … u_pixel_um``, or the library's
    ``x, y, alpha, pixelSize``), ``status, reason``; empty cells where there is no pose."""
    if convention == "vernier":
        columns, fields = found.library_pose(), ("x", "y", "alpha", "pixelSize")
    else:
        columns, fields = found.columns, FIELDS
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["file", "page", "number", *fields, "status", "reason"])
    for k in range(len(found)):
        path, page = origin[found.frame[k]]
        values = [float(columns[f][k]) for f in fields]
        w.writerow(
            [
                path,
                page,
                "" if found.number[k] < 0 else int(found.number[k]),
                *(
                    "" if math.isnan(v) else f"{v:.6f}" if abs(v) >= 1e-3 or v == 0 else f"{v:.6g}"
                    for v in values
                ),
                found.status[k],
                found.reason[k],
            ]
        )
    return buf.getvalue()
