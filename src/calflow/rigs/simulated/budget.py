"""The error budget of a calibration on a simulated stage, by replays with one effect off.

Test and report use only: it reads the simulated rig's effects, which analysis never does.

A family's calibration is replayed in-process on its simulated rig with one effect of its
table (:mod:`.effects`) switched off at a time, with the campaign's seeds and noise streams;
one more replay, the *baseline*, has every effect off. Per model, the score is the mean
square of the per-target systematic errors at the held-out targets, MS = mean_k AP_k². With
every effect on,

    MS_full = MS_baseline + Σ_e ΔMS_e + MS_interaction,   ΔMS_e = MS_full − MS_{−e},

ΔMS_e what switching ``e`` off removes and the interaction the remainder (effects that add
or cancel are not additive); an entry is sign(ΔMS)·√|ΔMS| (:func:`decompose`), so the
entries combine in signed quadrature to the RMS of the AP_k.

The driver is one command for every family, ``calflow error-budget --campaign FILE --out
FILE.json [--jobs N]`` (:func:`budget_command`): the family gives ``budget(campaign_path,
campaign, jobs) -> dict``, which runs its :class:`Replays`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from calflow.errors import CalflowError

BASELINE, NONE = "baseline", "none"  # every effect off; the campaign's own rig


def signed_root(value: float) -> float:
    """sign(v)·√|v|: a signed mean square as a signed length."""
    return float(np.sign(value) * np.sqrt(abs(value)))


def mean_square(values) -> float:
    return float(np.mean(np.asarray(values, dtype=float) ** 2))


def decompose(full, baseline, without: Mapping[str, Any]) -> tuple[float, dict[str, float]]:
    """The RMS of the per-target errors ``full`` and its budget: ``baseline`` (√MS of the
    baseline replay's), each effect's signed entry from the replay ``without[e]`` (module
    docstring) and ``interaction``; Σ sign·v² over the budget = RMS²."""
    ms, ms_base = mean_square(full), mean_square(baseline)
    delta = {e: ms - mean_square(v) for e, v in without.items()}
    budget = {
        BASELINE: float(np.sqrt(ms_base)),
        **{e: signed_root(d) for e, d in delta.items()},
        "interaction": signed_root(ms - ms_base - sum(delta.values())),
    }
    return float(np.sqrt(ms)), budget


@dataclass(frozen=True)
class Replays:
    """The replays of a family's budget: ``options(name)`` the rig options of a replay (every
    effect off for ``baseline``, one effect off, none for ``none``), ``active(campaign)`` the
    replays the campaign's rig has on, ``heldout(campaign, options)`` the calibration replayed
    with those options, its per-target held-out errors by model, stored under ``key``."""

    options: Callable[[str], dict]
    active: Callable[[Any], Sequence[str]]
    heldout: Callable[[Any, dict], dict]
    key: str = "ap"
    always: tuple[str, ...] = (BASELINE, NONE)  # replays that run whatever the rig has on

    def replay(self, campaign, name: str) -> dict:
        """One replay: its per-target held-out errors by model, or ``active: false`` when the
        campaign's rig has that effect off already."""
        if name not in self.always and name not in self.active(campaign):
            return {"replay": name, "active": False}
        options = self.options(name)
        return {"replay": name, "active": True, "options": options, self.key: self.heldout(campaign, options)}

    def run(self, campaign, names: Iterable[str], workers: int = 1) -> list[dict]:
        """:meth:`replay` of each of ``names``, over ``workers`` processes (no more than
        replays; ``campaign`` then a file name, and the family's callables module-level)."""
        names = list(names)
        if min(workers, len(names)) <= 1:
            return [self.replay(campaign, n) for n in names]
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(workers) as pool:
            return list(pool.map(self.replay, [campaign] * len(names), names))


def effects_of(records: Iterable[dict], skip: Iterable[str] = ()) -> tuple[dict[str, dict], list[str]]:
    """The active replays by name (without ``skip``) and the effects among them."""
    skip = set(skip)
    by = {r["replay"]: r for r in records if r.get("active") and r["replay"] not in skip}
    return by, [n for n in by if n not in (BASELINE, NONE)]


def require_simulated(campaign: Mapping[str, Any], where: str, family: bool = True) -> None:
    """One line naming ``where`` (the campaign) when its rig is not the simulated one (or the
    campaign is not of the family: ``family`` false)."""
    factory = campaign["rig"]["factory"]
    if factory != "simulated" or not family:
        raise CalflowError(
            f"{where}: key 'rig.factory': the error budget needs the simulated rig "
            f"(it replays the calibration on the rig's truth), got {factory!r}"
        )


def budget_command(budget: Callable[[str, dict, int], dict]) -> Callable[[Any], None]:
    """``calflow error-budget --campaign FILE --out FILE.json [--jobs N]`` of a family whose
    ``budget(campaign_path, campaign, jobs)`` computes the budget: written as JSON for the
    summary step (tests and reports only)."""

    def error_budget_command(args) -> None:
        from calflow.configuration.handed import campaign_of
        from calflow.data.io import output_folder, write_json

        c = campaign_of(args)
        result = budget(args.campaign, c, max(1, int(getattr(args, "jobs", 1) or 1)))
        output_folder(args.out)
        write_json(result, args.out)

    return error_budget_command
