"""The 1-DoF and 2-DoF piezo nanopositioning stages under an interferometer (thesis Chapter 5).

Plans, the simulated stages and their thermal behaviour, the geometric, thermal, single
and adaptive kilometre-zero models (Eq. 5.1–5.10), the run-time controllers of the
five-day validation, evaluation with robustness indices, summary, report figures and the
CLI steps. What it registers with the core is in :mod:`~calflow.nano.family`.
"""
