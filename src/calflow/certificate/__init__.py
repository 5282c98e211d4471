"""Calibration certificates: the uncertainty of every headline figure and its conformity.

A robot family says what its headline figures are measured from and what its sensor
contributes to their uncertainty (``Family.uncertainty``: ``function(campaign, files) ->
list[Measurement]``), and which figures it computes with and without U
(``Family.certified``). The core does the rest: the budgets and U
(:mod:`calflow.metrics.uncertainty`), the decisions against the stage's specification
(:mod:`calflow.certificate.conformity`), the summary keys (:mod:`calflow.certificate.annotate`) and the
certificate page (:mod:`calflow.certificate.page`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # the workflow imports this package at load: no numpy there
    from calflow.metrics.uncertainty import Term

KINDS = ("iso9283", "iso230_2", "none")
#: What a measurement states of the item: as found (before anything was adjusted, through
#: the compensation in use), as left (after this calibration), or "" (a result of neither,
#: e.g. a characterisation of the uncompensated axes).
STATES = ("as_found", "as_left", "")


@dataclass(frozen=True)
class Measurement:
    """Where a family's headline figures are in its summary and the data they come from.

    * ``path``: the keys down to the summary's mapping holding the figures, e.g.
      ``("models", "III")``; ``keys``: result name → the figure's key there, e.g.
      ``{"accuracy": "accuracy_um", "repeatability": "repeatability_um"}`` for ``iso9283``
      or ``{"E": "E_um", …}`` for ``iso230_2``.
    * ``kind``: ``iso9283`` (``data``: ``command`` (T, d), ``attained`` T arrays (n, d),
      optional ``origin``), ``iso230_2`` (``targets``, ``forward``, ``backward``, optional
      ``origin``) or ``none`` (figures calflow states without U).
    * ``terms``: the sensor's declared terms (:class:`calflow.metrics.uncertainty.Term`),
      in the data's unit; ``scale``: the summary's unit per data unit (1000 for nm from µm).
    * ``label``: how the certificate names the measurement; ``notes``: what the budget
      leaves out, in words.
    * ``state``: one of :data:`STATES`; the certificate decides as found and as left apart.
    * ``traceability``: the sensor's chain to the SI metre, one link per entry, in words
      (e.g. "laser wavelength of the interferometer"); the certificate's traceability
      statement is built from them.
    """

    path: tuple[str, ...]
    keys: Mapping[str, str]
    kind: str = "iso9283"
    data: Mapping[str, Any] = field(default_factory=dict)
    terms: tuple[Term, ...] = ()
    scale: float = 1.0
    label: str = ""
    notes: tuple[str, ...] = ()
    state: str = ""
    traceability: tuple[str, ...] = ()

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"measurement {self.path}: kind {self.kind!r}; expected one of {KINDS}")
        if self.state not in STATES:
            raise ValueError(f"measurement {self.path}: state {self.state!r}; expected one of {STATES}")


__all__ = ["KINDS", "STATES", "Measurement"]
