"""ISO 9283 drift of pose characteristics dAP and dRP (ISO 9283:1998, clause 7.7).

The same command pose is measured at the start (t = 1) and at the end (t = T) of a long
period of operation (the standard: 8 h of cycling); AP and RP at each end are those of
clause 7.2 (:func:`calflow.metrics.iso9283`):

    dAP = |AP_{t=1} - AP_{t=T}|,   dRP = |RP_{t=1} - RP_{t=T}|.

Lengths in the unit of the inputs; the period T is the caller's to state.
"""

from __future__ import annotations

from dataclasses import dataclass

from .iso9283 import ISO9283Result, iso9283

__all__ = ["DriftResult", "iso9283_drift"]


@dataclass(frozen=True, eq=False)
class DriftResult:
    """dAP and dRP of one command pose (unit of the inputs), with both ends' results."""

    dap: float
    drp: float
    first: ISO9283Result
    last: ISO9283Result


def iso9283_drift(command, attained_first, attained_last) -> DriftResult:
    """Drift of pose accuracy dAP and of pose repeatability dRP (ISO 9283, 7.7).

    Parameters
    ----------
    command : array_like (d,), or a scalar for d = 1
        The command pose, any length unit.
    attained_first, attained_last : array_like (n, d), or (n,) for d = 1
        Positions attained at the start (t = 1) and at the end (t = T) of the period,
        n >= 2 each (the two counts may differ).  Same unit as ``command``.

    Returns
    -------
    DriftResult
        ``dap`` = |AP_T - AP_1| and ``drp`` = |RP_T - RP_1|, in the unit of the inputs.
    """
    try:
        first = iso9283(command, attained_first)
    except ValueError as exc:
        raise ValueError(f"first measurement: {exc}") from None
    try:
        last = iso9283(command, attained_last)
    except ValueError as exc:
        raise ValueError(f"last measurement: {exc}") from None
    return DriftResult(dap=abs(last.ap - first.ap), drp=abs(last.rp - first.rp), first=first, last=last)
