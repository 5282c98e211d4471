"""Expanded uncertainty U of the headline figures: the budget's terms, GUM, Welch–Satterthwaite,
Monte Carlo and the interval of a maximum (the figures themselves: :mod:`.uncertainty_iso`).

The budget of a metric has the finite sample of targets and cycles (Type A, from the data:
the within-target scatter pooled over targets, with its degrees of freedom) and the
sensor's own terms (Type B, declared by the robot family: calibration, alignment,
temperature, reference standard; :class:`Term`). A term acts on the mean reading at a
target in one of three ways (``scope``):

* ``common``: one error shared by every target of the measurement (an offset, or with
  ``relative`` a scale error in 1e-6 of the position: the sensor's calibration, its
  alignment's cosine error, the reference standard);
* ``target``: an independent error at each target (and direction): drift of the sensor
  with temperature between visits, nonlinearity;
* ``reading``: a per-reading error (noise, resolution). It is in the observed scatter
  already, so it enters through the sample term; the budget lists it for reference only.

Metrics linear in the inputs (the signed mean reversal B̄, a mean deviation) are
propagated with the GUM law (JCGM 100:2008, Eq. 10) and a coverage factor from Student's
t at the Welch–Satterthwaite effective degrees of freedom (JCGM 100 G.4.1). AP (the length
of a mean vector) and the maxima (AP and RP are maxima over targets; ISO 230-2's E, M, B,
A, R maxima and ranges) are propagated by Monte Carlo (JCGM 101:2008) with JCGM 101 §7.9's adaptive number of trials
(blocks of 10⁴ until the interval's ends and U are stable to the numerical tolerance of u,
:mod:`.adaptive`; ``trials`` fixes M instead), seeded so a result reproduces to the byte and
streamed so that memory holds one block of a few cells (:mod:`.stream`): the variance of
the scatter is drawn from its scaled inverse χ² (ν s²/χ²_ν), the means given it from
normals (JCGM 101 6.4.9), the Type B terms from normals with their standard uncertainty.
A maximum of noisy means is biased upwards and so are trials drawn around it, so the
JCGM 101 probabilistically symmetric interval of the maximum covers its true value too
rarely when targets nearly tie (≈ 86 % for eight targets three cycles each, measured);
the 95 % interval is built instead from each target's bias-corrected percentile interval
and Šidák's adjustment over the targets that can be the maximum, those whose paired
difference to the largest is not significantly negative (:func:`maximum_interval`,
:func:`.montecarlo.candidates`). U is the interval's half-width, ``dof_eff`` the
Welch–Satterthwaite degrees of freedom of the budget, k = t_0.975(ν_eff) and u = U/k (the
trials' own standard deviation does not exist when the scatter is known from few
readings). Each term's contribution in ``budget`` is the robust standard deviation (half
the central 68 % range) of the metric with that term alone.

The measurand of RP (and of ISO 230-2's A and R) is the population value of the scatter
(isotropic normal, pooled over targets): RP∞ = σ (E[χ_d] + 3 SD[χ_d]), what the ISO
formula l̄ + 3 S_l tends to with many cycles; with few cycles the ISO value is biased low
and may lie outside the interval — the record says so in ``note``.
"""

from calflow.metrics.uncertainty.budget import (
    P95,
    SCOPES,
    TRIALS,
    Term,
    Uncertainty,
    check_terms,
    coverage_factor,
    gum_linear,
    pooled_scatter,
    reading_budget,
    sigma_interval,
    welch_satterthwaite,
)
from calflow.metrics.uncertainty.draws import Draws
from calflow.metrics.uncertainty.montecarlo import (
    MAX_METHOD,
    chi_rp_factor,
    effective_count,
    how_drawn,
    largest_bounds,
    maximum_interval,
    mc_record,
    mc_result,
    robust_sd,
    standard_u,
)

__all__ = [
    "MAX_METHOD",
    "P95",
    "SCOPES",
    "TRIALS",
    "Draws",
    "Term",
    "Uncertainty",
    "chi_rp_factor",
    "check_terms",
    "coverage_factor",
    "effective_count",
    "gum_linear",
    "largest_bounds",
    "maximum_interval",
    "how_drawn",
    "mc_record",
    "mc_result",
    "pooled_scatter",
    "reading_budget",
    "robust_sd",
    "sigma_interval",
    "standard_u",
    "welch_satterthwaite",
]
