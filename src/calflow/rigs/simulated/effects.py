"""The effects table of a simulated stage, and what follows from it.

A family declares each effect of its simulated stage once, as an :class:`Effect`: the
option fields that switch it off (all at their off value: the effect is off), where its
form and magnitude come from (thesis equation or table, datasheet, standard), and whether a
calflow model of the family represents it. From that one table come

* the ``unmodelled`` switch: ``unmodelled: false`` turns off, in one key, every effect no
  model represents (:meth:`Effects.unmodelled_off`, or :class:`SwitchedTruth` for a frozen
  dataclass of the physics);
* rig options with some effects off, for tests, studies and the error budget's replays
  (:meth:`Effects.options_off`, :meth:`Effects.without`);
* the effects a rig has on (:meth:`Effects.active`).

An :class:`Effects` is a mapping ``effect name → its fields`` (so ``EFFECTS[name]`` are the
fields that switch it off), in the declared order.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, replace
from typing import Any, ClassVar, NamedTuple, dataclass_transform

import numpy as np


def off(value):
    """The switched-off value of an effect's field: False, 0.0, or a tuple of zeros."""
    if isinstance(value, bool):
        return False
    return tuple(0.0 for _ in value) if isinstance(value, tuple) else 0.0


class Effect(NamedTuple):
    """One effect of a simulated stage: the fields that switch it off, its source, and
    whether a calflow model of the family represents it."""

    fields: tuple[str, ...]
    source: str
    modelled: bool = True


class Effects(Mapping[str, tuple[str, ...]]):
    """The effects table: effect name → :class:`Effect`; as a mapping, name → its fields."""

    def __init__(self, table: Mapping[str, Effect], kind: str = "") -> None:
        self.table = dict(table)
        self.kind = kind  # how errors name the stage's effects ("<kind> effect(s)")

    def __getitem__(self, name: str) -> tuple[str, ...]:
        return self.table[name].fields

    def __iter__(self) -> Iterator[str]:
        return iter(self.table)

    def __len__(self) -> int:
        return len(self.table)

    def source(self, name: str) -> str:
        return self.table[name].source

    def modelled(self, name: str) -> bool:
        return self.table[name].modelled

    @property
    def unmodelled(self) -> tuple[str, ...]:
        """The effects no calflow model represents, in the table's order."""
        return tuple(name for name, e in self.table.items() if not e.modelled)

    @property
    def unmodelled_fields(self) -> tuple[str, ...]:
        """The fields of the effects no calflow model represents."""
        return tuple(f for name in self.unmodelled for f in self.table[name].fields)

    def check(self, effects) -> None:
        """Raise ``ValueError`` naming the effects that are not in the table."""
        unknown = [e for e in effects if e not in self.table]
        if unknown:
            kind = f"{self.kind} effect(s)" if self.kind else "effect(s)"
            raise ValueError(f"unknown {kind} {unknown}; expected some of {sorted(self.table)}")

    def without(self, options: Mapping[str, Any], *effects: str) -> dict[str, Any]:
        """``options`` with the fields of ``effects`` at their off value; fields the options
        lack are skipped."""
        self.check(effects)
        out = dict(options)
        for name in effects:
            for key in self.table[name].fields:
                if key in out:
                    out[key] = off(out[key])
        return out

    def unmodelled_off(self, options: Mapping[str, Any]) -> dict[str, Any]:
        """The ``unmodelled`` switch: ``options`` as they are, or, when their ``unmodelled`` is
        false, with every effect no model represents off."""
        if options.get("unmodelled", True):
            return dict(options)
        return self.without(options, *self.unmodelled)

    def options_off(self, defaults: Mapping[str, Any], *effects: str) -> dict[str, Any]:
        """Rig options (lists for tuples, as in a campaign file) that switch off ``effects``
        (all of them when none is named), from the rig's ``defaults``."""
        names = effects or tuple(self.table)
        self.check(names)
        out: dict[str, Any] = {}
        for name in names:
            for f in self.table[name].fields:
                value = off(defaults[f])
                out[f] = list(value) if isinstance(value, tuple) else value
        return out

    def active(self, values) -> list[str]:
        """The effects that ``values`` (a mapping of the options, or an object with them as
        attributes) have on: any of their fields not at zero."""
        get = values.get if isinstance(values, Mapping) else lambda f: getattr(values, f)
        return [
            name for name, e in self.table.items() if any(np.any(np.asarray(get(f)) != 0) for f in e.fields)
        ]


@dataclass_transform(frozen_default=True)
@dataclass(frozen=True)
class SwitchedTruth:
    """Base of a simulated stage's true physics: ``class StageTruth(SwitchedTruth,
    effects=EFFECTS)`` is a frozen dataclass (made one here) whose fields are the rig's options,
    with its :class:`Effects` table as the class attribute ``EFFECTS``. Its ``unmodelled`` field
    is the switch of the table's unmodelled effects: false, every effect no model represents
    is off (the fields of :attr:`Effects.unmodelled_fields`)."""

    EFFECTS: ClassVar[Effects]

    def __init_subclass__(cls, effects: Effects | None = None, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if effects is not None:
            cls.EFFECTS = effects
        dataclass(frozen=True)(cls)

    def __post_init__(self) -> None:  # the table's switch (:meth:`Effects.unmodelled_off`) on the fields
        fields = {name: getattr(self, name) for name in (*self.EFFECTS.unmodelled_fields, "unmodelled")}
        for name, value in self.EFFECTS.unmodelled_off(fields).items():
            object.__setattr__(self, name, value)

    def without(self, *fields: str):
        """The same physics with ``fields`` (field names) switched off."""
        return replace(self, **{name: off(getattr(self, name)) for name in fields})

    def as_dict(self) -> dict:
        from dataclasses import asdict

        return asdict(self)
