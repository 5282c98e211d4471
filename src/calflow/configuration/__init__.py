"""What a run is told and where it writes: the one YAML loader, the workflow configuration
and the campaign files checked against their schemas, and the layout of ``results/`` and
``reports/``.
"""
