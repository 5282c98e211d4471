"""Two CI runs of the same commit draw the same hypothesis examples (the ``ci`` profile of
tests/hypothesis_profiles.py, chosen by ``CI=true``)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

# A property test as the suite writes them (floats, lists, sampled values), which records
# every example it is given. Run in a process of its own, as a CI job is: a run started
# under the same profile must give the same list.
PROBE = textwrap.dedent(
    """
    import json, sys
    from hypothesis import given, strategies as st
    drawn = []

    @given(st.lists(st.floats(-1e3, 1e3, allow_nan=False), min_size=1, max_size=5), st.sampled_from("abc"))
    def probe(xs, c):
        drawn.append([xs, c])

    probe()
    from hypothesis import settings
    print(json.dumps([settings.default.derandomize, settings.default.database is None, drawn]))
    """
)


def _draw(tmp_path: Path, **env) -> list:
    import json

    script = tmp_path / "probe_run.py"
    # the profiles conftest.py loads (tests/hypothesis_profiles.py), as pytest does
    script.write_text(
        f"import sys; sys.path.insert(0, {str(ROOT / 'tests')!r}); import hypothesis_profiles\n{PROBE}"
    )
    clean = {k: v for k, v in os.environ.items() if k not in ("CI", "HYPOTHESIS_PROFILE")}
    proc = subprocess.run(
        [sys.executable, str(script)], env={**clean, **env}, capture_output=True, text=True, cwd=tmp_path
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_two_ci_runs_draw_the_same_examples(tmp_path):
    """Each run in a process of its own (as two CI jobs; Python's hash seed differs)."""
    first, second = _draw(tmp_path, CI="true"), _draw(tmp_path, CI="true")
    assert first[:2] == [True, True]  # derandomised, and no example database carried over
    assert len(first[2]) > 10 and first == second
