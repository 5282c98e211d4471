"""Test hook: each ``calflow`` process of a test's workflow run records, as it exits, the
calflow and family modules it imported (``$CALFLOW_MODULE_LOG/<pid>.json``), so
tests/project/test_provenance.py can check that each job's rerun digest covers all of them.

On ``PYTHONPATH`` only in the workflow runs of tests/conftest.py; does nothing unless
``CALFLOW_MODULE_LOG`` names a folder.
"""

import atexit
import json
import os
import sys


def _record() -> None:
    folder = os.environ.get("CALFLOW_MODULE_LOG")
    if not folder or len(sys.argv) < 2 or os.path.basename(sys.argv[0]) != "calflow":
        return
    from importlib.metadata import entry_points

    tops = {"calflow"} | {ep.value.split(".")[0] for ep in entry_points(group="calflow.families")}
    modules = sorted(m for m in list(sys.modules) if m.split(".")[0] in tops)
    with open(os.path.join(folder, f"{os.getpid()}.json"), "w") as f:
        json.dump({"argv": sys.argv[1:], "cwd": os.getcwd(), "modules": modules}, f)


atexit.register(_record)
