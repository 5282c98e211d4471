"""The XYΘ micro-robot under a microscope (thesis Chapter 4).

Kinematics (:mod:`~calflow.xytheta.models.kinematics`, Eq. 4.18–4.22), plans and sweeps, the
simulated rig and its vision sensor, the pose-difference identification (Eq. 4.27–4.30),
Models I–V and their lookup tables, characterisation, evaluation, summary, report figures,
the Monte-Carlo study and the CLI steps. What it registers with the core is in
:mod:`~calflow.xytheta.family`.
"""
