"""The summary's job draws no figure: the modules it imports leave matplotlib (about a
second of every summary job's start) to the report's."""

from __future__ import annotations

import json
import subprocess
import sys


def test_the_summary_and_its_certificate_figures_import_no_matplotlib():
    code = (
        "import json, sys\n"
        "import calflow.certificate.annotate, calflow.nano.certificate\n"
        "import calflow.xytheta.report.summary, calflow.xytheta.report.certificate\n"
        "import calflow.xytheta.report.instrument\n"
        "print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] == 'matplotlib')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert json.loads(out.stdout) == []
