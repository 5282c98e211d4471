"""calflow's cache between processes: small JSON results kept under a hash of all they depend
on (content-addressed, so never stale), e.g. the normalised sources of the rerun digests
(:mod:`calflow.provenance`) and the hook bindings read at registration
(:mod:`calflow.hook_source`)."""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from functools import cache
from pathlib import Path


@cache
def cache_dir() -> Path | None:
    """``$CALFLOW_CACHE_DIR``, else ``$XDG_CACHE_HOME/calflow`` or ``~/.cache/calflow``; empty
    ``CALFLOW_CACHE_DIR``: none (everything computed each time)."""
    folder = os.environ.get("CALFLOW_CACHE_DIR")
    if folder is None:
        folder = os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "calflow")
    return Path(folder) if folder else None


def cached_json(kind: str, key: str, compute: Callable[[], dict]) -> dict:
    """``compute()``, a JSON-able dict, kept in the cache's ``kind`` folder under ``key``."""
    root = cache_dir()
    cached = root / kind / f"{key}.json" if root else None
    if cached is not None:
        try:
            return json.loads(cached.read_text())
        except (OSError, ValueError):
            pass
    found = compute()
    if cached is not None:
        try:
            cached.parent.mkdir(parents=True, exist_ok=True)
            tmp = cached.with_suffix(f".{os.getpid()}.tmp")
            tmp.write_text(json.dumps(found))
            tmp.replace(cached)
        except OSError:  # a read-only home: computed again next time
            pass
    return found
