"""A stage's life: its calibrations in time order, whether it changed between them, control
charts of its parameters and accuracy, interim checks, and when it is due for recalibration.

The modules are family-neutral: a robot family hands over, through its registered
:class:`calflow.family.Family` (``history_entry``), each campaign's parameters with their
covariance and its held-out accuracy; everything here works on those numbers only
(docs/lifecycle.md).
"""
