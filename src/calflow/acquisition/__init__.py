"""Acquisition: a plan run on a rig becomes a run dataset.

:mod:`~calflow.acquisition.runner` runs the plan (open loop or through a controller),
:mod:`~calflow.acquisition.checkpoint` journals completed samples so an interrupted run
resumes, :mod:`~calflow.acquisition.streams` reduces high-rate streams to one reading per
dwell, :mod:`~calflow.acquisition.progress` shows progress on a terminal.
"""
