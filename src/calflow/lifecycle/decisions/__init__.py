"""The decisions of a stage's history: did it change between two calibrations
(``change``), control charts of its parameters and accuracy (``charts``), the interim
check's sequential test (``sprt``), the due date from the accuracy's trend (``due``),
and the calibration interval from as-found drift (``interval``, ``as_found``).
"""
