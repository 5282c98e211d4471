"""How the plug-in's benchmarks print their figures: one JSON line (``--json``) or one aligned
``key: value`` line per figure."""

from __future__ import annotations

import json


def print_figures(out: dict, as_json: bool) -> None:
    """Print the benchmark's figures ``out``, as one JSON line when ``as_json``."""
    if as_json:
        print(json.dumps(out))
        return
    width = max(map(len, out), default=0)
    for key, value in out.items():
        print(f"{key:>{width}}: {value}")
