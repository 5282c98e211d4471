"""The options of a simulated stage checked against its declaration, one line per fault.

The declaration is the frozen dataclass of the stage's physics (:mod:`.effects`): each
field an option, its default giving the option's kind — true/false for a ``bool``, an
integer ≥ 0 for an ``int`` (seeds), one of a few words for a ``str``, a list of as many
numbers for a ``tuple``, a number otherwise — and a :class:`Bounds` the sign a number
may take. :func:`check_physics` checks a rig's options against it and converts them; a
fault raises :class:`~calflow.errors.OptionError` naming the option and what was expected.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from calflow.errors import OptionError, UnknownOptionError

_EXPECTED = {None: "a finite number", ">": "a finite number > 0", ">=": "a finite number >= 0"}
_EACH = {None: "finite", ">": "finite and > 0", ">=": "finite and >= 0"}


@dataclass(frozen=True)
class Bounds:
    """The sign each numeric option may take: > 0 (``positive``), ≥ 0 (``non_negative``),
    any (``signed``), or ``default`` (None: any; ``">="``; ``">"``) for the others;
    ``choices`` the words a ``str`` option may be."""

    positive: tuple[str, ...] = ()
    non_negative: tuple[str, ...] = ()
    signed: tuple[str, ...] = ()
    default: str | None = None
    choices: Mapping[str, tuple[str, ...]] = field(default_factory=dict)

    def of(self, key: str) -> str | None:
        if key in self.positive:
            return ">"
        if key in self.non_negative:
            return ">="
        return None if key in self.signed else self.default


def number(key: str, value, bound: str | None) -> float:
    """``value`` as a float: a finite number, > 0 (``bound`` ``">"``) or ≥ 0 (``">="``)."""
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
    ok = ok and bool(np.isfinite(value)) and (bound is None or (value > 0 if bound == ">" else value >= 0))
    if not ok:
        raise OptionError(key, _EXPECTED[bound], value)
    return float(value)


def seed(key: str, value) -> int:
    """``value`` as a seed: an integer ≥ 0."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise OptionError(key, "an integer >= 0", value)
    return int(value)


def check_value(key: str, value, default, bounds: Bounds):
    """One option checked against its default's kind and its bound, converted."""
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise OptionError(key, "true or false", value)
        return value
    if isinstance(default, int):
        return seed(key, value)
    if isinstance(default, str):
        words = bounds.choices.get(key, ())
        if value not in words:
            raise OptionError(key, f"one of {', '.join(words)}", value)
        return value
    bound = bounds.of(key)
    if isinstance(default, tuple):
        if not isinstance(value, (list, tuple)) or len(value) != len(default):
            raise OptionError(key, f"a list of {len(default)} numbers", value)
        for v in value:
            try:
                number(key, v, bound)
            except OptionError:
                raise OptionError(
                    key, f"a list of {len(default)} numbers, each {_EACH[bound]}", value
                ) from None
        return tuple(float(v) for v in value)
    return number(key, value, bound)


def check_physics(
    truth: type,
    bounds: Bounds,
    seed_value=0,
    stream: str = "",
    physics: Mapping[str, Any] | None = None,
    also: Iterable[str] = (),
) -> dict[str, Any]:
    """The options of a simulated stage whose physics is the dataclass ``truth``: ``seed``
    (an integer ≥ 0), ``stream`` (a string) and ``physics``, each a field of ``truth``
    (:func:`check_value`); returns ``{"seed", "stream", **physics}`` converted. ``also``: the
    further option names the rig takes (checked elsewhere), for the unknown-name message."""
    known = {f.name: f.default for f in dataclasses.fields(truth)}
    physics = dict(physics or {})
    for key in physics:
        if key not in known:
            names = sorted([*known, *also])
            raise UnknownOptionError(key, f"expected one of: seed, stream, {', '.join(names)}")
    checked_seed = seed("seed", seed_value)
    if not isinstance(stream, str):
        raise OptionError("stream", "a string", stream)
    out = {key: check_value(key, value, known[key], bounds) for key, value in physics.items()}
    return {"seed": checked_seed, "stream": stream, **out}
