"""A fourth robot family, defined in the tests: a simulated 1-axis linear stage.

It registers with calflow exactly as a family in its own distribution does — an entry point of
the group ``calflow.families`` (the tests write its ``.dist-info`` on the path) — and keeps the
contract (:mod:`calflow.family_contract`) with no edit to calflow's core. Its stage reads
``meas_x = (1 + scale) * x + offset + noise``; identification fits the scale and offset.
"""
