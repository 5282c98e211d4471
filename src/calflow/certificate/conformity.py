"""Conformity with a specification: decision rules and the specific risk of a false accept.

A specification is an upper tolerance limit T per metric (AP, RP, E … are all "smaller is
better"). A decision rule (ISO/IEC 17025:2017 3.7, ILAC-G8:09/2019) turns a measured
value y with its expanded uncertainty U into a statement:

* ``simple``: simple acceptance (ILAC-G8 4.2.1, w = 0): pass if y ≤ T, else fail;
* ``guarded``: binary statement with a guard band w = U (ILAC-G8 4.2.2): pass if
  y ≤ T − U, else fail — the specific risk of a false accept is then ≤ 2.5 % for a
  symmetric 95 % interval;
* ``non-binary``: ILAC-G8 4.2.3, w = U: pass if y + U ≤ T, conditional pass if
  y ≤ T < y + U, conditional fail if y − U ≤ T < y, fail if T < y − U.

The specific probability of a false accept (JCGM 106:2012 9.3.2) of an accepting decision
is the probability that the measurand exceeds T given y: the measurand's distribution is
Student's t with the result's effective dof (normal when ∞), centred on y, with scale
u = U/k. A rejecting decision has no false-accept risk; its specific probability of a
false reject (P(Y ≤ T)) is given as ``pfr``.
"""

from __future__ import annotations

import math

from calflow.errors import ConfigError

RULES = {
    "simple": "simple acceptance (ILAC-G8:09/2019 4.2.1, guard band w = 0)",
    "guarded": "binary statement with guarded acceptance, w = U (ILAC-G8:09/2019 4.2.2)",
    "non-binary": "non-binary statement with guard band w = U (ILAC-G8:09/2019 4.2.3)",
}
ACCEPTS = ("pass", "conditional pass")
NEEDS_U = ("guarded", "non-binary")


def probability_above(value: float, u: float, dof: float | None, limit: float) -> float:
    """P(Y > limit) for Y = value + u·t_ν (normal for ν None or ∞; a point mass for u = 0)."""
    if u <= 0:
        return float(value > limit)
    from scipy import stats  # here: the workflow imports this module to check settings at load

    z = (limit - value) / u
    if dof is None or not math.isfinite(dof):
        return float(stats.norm.sf(z))
    return float(stats.t.sf(z, dof))


def decide(
    value: float, limit: float, rule: str, U: float | None = None, k: float | None = None, dof=None
) -> dict:
    """``{rule, spec, decision, pfa, pfr, guard_band}`` of ``value`` against upper limit ``limit``.

    ``U``, ``k``, ``dof``: the value's expanded uncertainty, coverage factor and effective
    dof (``None`` without an uncertainty: only ``simple`` then, and no risk is computed).
    """
    if rule not in RULES:
        raise ValueError(f"decision rule {rule!r}: expected one of {sorted(RULES)}")
    if not (isinstance(limit, (int, float)) and math.isfinite(limit) and limit > 0):
        raise ValueError(f"tolerance {limit!r}: expected a number > 0")
    if U is None and rule in NEEDS_U:
        raise ValueError(f"decision rule {rule!r} needs the result's U; it has none")
    y = float(value)
    if rule == "simple":
        decision, w = ("pass" if y <= limit else "fail"), 0.0
    elif rule == "guarded":
        decision, w = ("pass" if y <= limit - U else "fail"), float(U)
    else:
        w = float(U)
        if y + U <= limit:
            decision = "pass"
        elif y <= limit:
            decision = "conditional pass"
        elif y - U <= limit:
            decision = "conditional fail"
        else:
            decision = "fail"
    out = {
        "rule": rule,
        "spec": float(limit),
        "decision": decision,
        "guard_band": w,
        "pfa": None,
        "pfr": None,
    }
    if U is not None and k:
        p_out = probability_above(y, U / k, dof, limit)
        out["pfa"] = p_out if decision in ACCEPTS else 0.0
        out["pfr"] = 1.0 - p_out if decision not in ACCEPTS else 0.0
    return out


def check(settings: dict, metrics: dict[str, bool], file: str, prefix: str = "") -> dict:
    """The stage's ``specification`` and ``decision_rule``, checked; ``{}`` when it has none.

    ``metrics``: the metric names the stage's family computes, each with whether it has a
    U. Refused with one line naming ``file`` and the key (``prefix`` + its name, e.g.
    ``stages.SN-0042.``): an unknown rule, a tolerance
    that is not a number > 0, a metric the family does not compute, a guarded or
    non-binary rule on a metric without U.
    """
    spec = settings.get("specification")
    rule = settings.get("decision_rule", "simple" if spec else None)
    if spec is None and rule is None:
        return {}
    if rule not in RULES:
        raise ConfigError(
            f"{file}: key '{prefix}decision_rule': expected one of {', '.join(RULES)}, got {rule!r}"
        )
    if not isinstance(spec, dict) or not spec:
        raise ConfigError(
            f"{file}: key '{prefix}specification': expected a tolerance per metric, e.g. {{accuracy_um: 3.5}}"
        )
    for name, limit in spec.items():
        key = f"{file}: key '{prefix}specification.{name}'"
        if name not in metrics:
            raise ConfigError(
                f"{key}: the family does not compute {name!r}; expected one of {', '.join(sorted(metrics))}"
            )
        if (
            isinstance(limit, bool)
            or not isinstance(limit, (int, float))
            or not math.isfinite(limit)
            or limit <= 0
        ):
            raise ConfigError(f"{key}: expected a tolerance > 0, got {limit!r}")
        if rule in NEEDS_U and not metrics[name]:
            raise ConfigError(
                f"{key}: the {rule} rule puts a guard band w = U on it, but calflow computes no U for {name!r}; "
                "use decision_rule: simple or drop it"
            )
    return {"specification": {k: float(v) for k, v in spec.items()}, "decision_rule": rule}
