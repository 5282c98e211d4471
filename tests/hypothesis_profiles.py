"""Hypothesis's profiles for the suite, as its docs recommend (imported by conftest.py).

"ci" draws the same examples on every run (derandomize: a red CI run is a real failure,
reproduced by the next one), "dev" explores fresh examples each run and remembers its finds
in .hypothesis/, "explore" draws 1000 a test. CI=true selects "ci"; HYPOTHESIS_PROFILE names
one. A find worth keeping becomes an @example on its test.
"""

from __future__ import annotations

import os

from hypothesis import HealthCheck, settings

settings.register_profile(
    "ci", derandomize=True, database=None, deadline=None, print_blob=True,
    suppress_health_check=[HealthCheck.too_slow],
)  # fmt: skip
settings.register_profile("dev", deadline=None)
settings.register_profile("explore", deadline=None, max_examples=1000)
settings.load_profile(
    os.environ.get("HYPOTHESIS_PROFILE")
    or ("ci" if os.environ.get("CI", "").lower() in ("1", "true") else "dev")
)
