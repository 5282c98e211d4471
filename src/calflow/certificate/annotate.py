"""The certificate keys of a campaign summary: ``uncertainty`` and ``conformity`` per figure.

Beside each headline figure its family measures (``Family.uncertainty``), the summary gets

* ``<parent>.uncertainty.<key> = {U, k, dof_eff, budget: {term: u}, u, interval, coverage,
  method, value, notes}`` in the figure's unit (:mod:`calflow.metrics.uncertainty`), and,
  when the stage's settings state a specification,
* ``<parent>.conformity.<key> = {rule, spec, decision, pfa, pfr, guard_band}``
  (:mod:`calflow.certificate.conformity`); a model's ``as_found`` values (when the summary has them)
  get theirs in ``as_found.conformity``;
* ``certificate = {specification, decision_rule, rule_text, decision, figures}`` at the top:
  the campaign's worst decision and the list of figures with a U.

The summary step runs this after the family's summary (``calflow summarise``); it reads
result files only, never the simulated truth.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

from calflow.certificate import conformity
from calflow.configuration.campaign import dig
from calflow.errors import ConfigError
from calflow.family import family_of, resolve

if TYPE_CHECKING:  # the workflow imports this module to check settings at load: no numpy there
    from calflow.certificate import Measurement
    from calflow.metrics.uncertainty import Uncertainty

ORDER = ("pass", "conditional pass", "conditional fail", "fail")


def certified(robot: str) -> dict[str, bool]:
    """The figures the robot's family computes, each with whether calflow gives its U."""
    return dict(family_of(robot).certified.get(robot, {}))


def check_settings(settings: dict, robot: str, file: str, prefix: str = "") -> dict:
    """A stage's ``specification`` and ``decision_rule`` checked against its family's figures."""
    return conformity.check(settings or {}, certified(robot), file, prefix)


def check_stages(settings: dict, campaigns: dict[str, dict], groups: dict[str, list[str]], file: str) -> None:
    """Each configured stage's specification and rule (config ``stages.<id>``), checked against
    the family of its campaigns (``groups``: stage → campaign names, :func:`calflow.lifecycle.stages.stages_of`)."""
    for stage, values in (settings or {}).items():
        if stage in groups and isinstance(values, dict):
            check_settings(values, campaigns[groups[stage][0]]["robot"], str(file), f"stages.{stage}.")


def _dig(summary: dict, path: tuple[str, ...]):
    node = dig(summary, path)
    return node if isinstance(node, dict) else None


def uncertainties(m: Measurement, iso230_2: Callable | None = None) -> dict[str, Uncertainty]:
    """The U of a measurement's figures (its family's data and terms); ``iso230_2``: what
    computes an ISO 230-2 run's (its arguments and results those of
    :func:`calflow.metrics.uncertainty_iso.iso230_2_uncertainty`, the default)."""
    from calflow.metrics.uncertainty_iso import iso230_2_uncertainty, iso9283_uncertainty

    d = m.data
    if m.kind == "iso9283":
        return iso9283_uncertainty(d["command"], d["attained"], m.terms, origin=d.get("origin"))
    if m.kind == "iso230_2":
        return (iso230_2 or iso230_2_uncertainty)(
            d["targets"], d["forward"], d["backward"], m.terms, origin=d.get("origin", 0.0)
        )
    return {}


def record(u: Uncertainty, scale: float, value, notes=()) -> dict:
    """``u.record()`` in the summary's unit, with the value it is the U of."""
    r = u.record()
    r["U"], r["u"] = r["U"] * scale, r["u"] * scale
    r["interval"] = [v * scale for v in r["interval"]]
    r["budget"] = {k: v * scale for k, v in r["budget"].items()}
    if "tolerance" in r.get("monte_carlo", {}):  # the numerical tolerance and 2 s, in the figure's unit
        r["monte_carlo"] = {
            **r["monte_carlo"],
            "tolerance": r["monte_carlo"]["tolerance"] * scale,
            "spread": r["monte_carlo"]["spread"] * scale,
        }
    r["value"] = value if value is not None else u.value * scale
    mine = u.value * scale
    if isinstance(value, (int, float)) and not math.isclose(mine, value, rel_tol=5e-3, abs_tol=1e-9 * scale):
        r["mismatch"] = (
            f"the data the U was computed from give {mine:.6g}, the summary {value:.6g}: "
            "the U may not describe this value"
        )
    if notes:
        r["notes"] = list(notes)
    return r


def _decide(value, limit, rule, unc: dict | None) -> dict:
    if not isinstance(value, (int, float)) or not math.isfinite(value):
        return _undecided(limit, rule, "no value")
    if unc is None and rule in conformity.NEEDS_U:
        return _undecided(limit, rule, f"this value has no U: the {rule} rule cannot decide")
    if unc is None:
        return conformity.decide(value, limit, rule)
    return conformity.decide(value, limit, rule, unc["U"], unc["k"], unc["dof_eff"])


def least_favourable(decisions) -> str | None:
    """The least favourable of ``decisions`` (None among them ignored), or None."""
    known = [d for d in decisions if d is not None]
    return max(known, key=ORDER.index) if known else None


def _found_uncertainty(parent: dict, found: dict, key: str) -> dict | None:
    """The U of a nested ``as_found`` value: its own, or its parent's when the block repeats
    the parent's value (an interim check's as-found value is the check's own AP)."""
    own = (found.get("uncertainty") or {}).get(key)
    if own is not None:
        return own
    mine = (parent.get("uncertainty") or {}).get(key)
    if mine is not None and found.get(key) == parent.get(key):
        found.setdefault("uncertainty", {})[key] = mine
        return mine
    return None


def annotate(
    summary: dict,
    campaign: dict,
    files: list[str],
    settings: dict | None = None,
    iso230_2: Callable | None = None,
) -> dict:
    """``summary`` with the certificate keys (module notes); ``settings``: the stage's;
    ``iso230_2``: what computes an ISO 230-2 run's U (:func:`uncertainties`; the summary step
    keeps a characterisation's between runs, :mod:`calflow.commands.kept`).

    As found and as left are decided apart (``certificate.decisions``): what the stage
    leaves the lab with, ``certificate.decision``, is the as-left decision when the campaign
    has one, else the least favourable of its other results, else the as-found decision.
    """
    from calflow.certificate.environment import environment

    robot = campaign["robot"]
    family = family_of(robot)
    prefix = f"stages.{campaign['stage']}." if campaign.get("stage") else ""
    spec = check_settings(settings, robot, "config/config.yaml", prefix) if settings else {}
    measurements = resolve(family.uncertainty)(campaign, files) if family.uncertainty else []
    figures, decisions, listed, chain = [], {"as_found": [], "as_left": [], "": []}, set(), []
    limits = spec.get("specification", {})
    rule = spec.get("decision_rule")
    for m in measurements:
        parent = _dig(summary, m.path)
        if parent is None:
            continue
        chain += [t for t in m.traceability if t not in chain]
        results = uncertainties(m, iso230_2)
        for name, key in m.keys.items():
            if key not in parent:
                continue
            unc = None
            if name in results:
                unc = record(results[name], m.scale, parent[key], m.notes)
                parent.setdefault("uncertainty", {})[key] = unc
                # one row per figure: the same value under two paths (a copy kept for the
                # history) is certified once
                if (m.label, key, parent[key]) not in listed:
                    listed.add((m.label, key, parent[key]))
                    figures.append(
                        {"path": list(m.path), "key": key, "label": m.label, "state": m.state, "kind": m.kind}
                    )
            if key in limits:
                c = _decide(parent[key], limits[key], rule, unc)
                parent.setdefault("conformity", {})[key] = c
                decisions[m.state].append(c["decision"])
        found = parent.get("as_found")
        if isinstance(found, dict):
            for key, limit in limits.items():
                if key in found:
                    c = _decide(found[key], limit, rule, _found_uncertainty(parent, found, key))
                    found.setdefault("conformity", {})[key] = c
                    decisions["as_found"].append(c["decision"])
    states = {s: least_favourable(d) for s, d in decisions.items()}
    overall = states["as_left"] or states[""] or states["as_found"]
    given = [d for ds in decisions.values() for d in ds]
    summary["certificate"] = {
        "specification": limits,
        "decision_rule": rule,
        "rule_text": conformity.RULES.get(rule) if rule else None,
        "decision": overall,
        "decisions": {
            "as_found": states["as_found"],
            "as_left": states["as_left"] or states[""],
        },
        "undecided": sum(d is None for d in given),
        "figures": figures,
        "traceability": chain,
        "environment": environment(files),
    }
    return summary


def json_object(text: str | None, where: str) -> dict:
    """A JSON object given on a command line (``{}`` when absent); anything else is refused in
    one line naming ``where`` (``calflow summarise: --settings``)."""
    import json

    if not text:
        return {}
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"{where}: expected JSON, got {text!r} ({exc})") from None
    if not isinstance(value, dict):
        raise ConfigError(f"{where}: expected a JSON object, got {text!r}")
    return value


def stage_settings_or_fail(text: str | None) -> dict:
    """The ``--settings`` JSON of ``calflow summarise`` (config ``stages.<id>``)."""
    return json_object(text, "calflow summarise: --settings")


def _undecided(limit, rule, why: str) -> dict:
    """A conformity entry without a decision, and why."""
    return {"rule": rule, "spec": limit, "decision": None, "pfa": None, "pfr": None, "statement": why}
