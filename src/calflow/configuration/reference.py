"""Published results put beside calflow's, for the campaigns that reproduce them.

Reference values belong to a campaign, not to a robot type: a campaign that reproduces a
published result declares it with the top-level key ``reference`` (docs/config.md):

* ``reference: <name>`` — a named reference set its robot's family provides
  (:attr:`calflow.family.Family.reference`, name → ``"module:attribute"`` of a dict with a
  ``source``);
* ``reference: {file: path/to/values.yaml}`` — a file of reference values: a mapping with a
  ``source`` (text naming the publication) and the values, nested mappings whose leaves are
  numbers or lists of numbers, keyed like the summary they sit beside.

A campaign without the key has no reference: its summary's ``reference`` is ``{}`` and its
report and index row show no reference column.
"""

from __future__ import annotations

import math
from pathlib import Path

from calflow.configuration import yamlfile
from calflow.errors import ConfigError


def _named(robot: str) -> dict[str, str]:
    """The reference sets of ``robot``'s family: name → ``"module:attribute"``."""
    from calflow.family import family_of

    return dict(family_of(robot).reference)


def _check_values(data, path: str, where: str = "") -> None:
    """Every leaf of a reference file's values is a finite number or a list of them."""
    if isinstance(data, dict):
        for key, value in data.items():
            if not isinstance(key, str):
                raise ConfigError(
                    f"{path}: key {key!r} under '{where or '<top level>'}': expected a text key"
                )
            _check_values(value, path, f"{where}.{key}" if where else key)
        return
    items = data if isinstance(data, list) else [data]
    for v in items:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ConfigError(
                f"{path}: key '{where}': expected a finite number, a list of numbers or a mapping, got {v!r}"
            )


def load_file(path: str | Path) -> dict:
    """The reference values of a file (YAML): ``source`` (required, text) and the values."""
    path = Path(path)
    data = yamlfile.load(path, "reference file")
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: <top level>: expected a mapping with 'source' and the values")
    source = data.get("source")
    if not isinstance(source, str) or not source.strip():
        raise ConfigError(f"{path}: key 'source': expected the text naming the publication, got {source!r}")
    values = {k: v for k, v in data.items() if k != "source"}
    if not values:
        raise ConfigError(f"{path}: <top level>: expected reference values beside 'source', found none")
    _check_values(values, str(path))
    return {"source": source, **values}


def _merged(a: dict, b: dict) -> dict:
    out = dict(a)
    for k, v in b.items():
        out[k] = _merged(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def template(robot: str) -> dict:
    """The keys a reference of ``robot`` may hold: the family's named sets merged (``{}`` when
    the family names none — then nothing tells a key from a typo)."""
    from calflow.family import resolve

    out: dict = {}
    for target in _named(robot).values():
        out = _merged(out, {k: v for k, v in resolve(target).items() if k != "source"})
    return out


def _check_keys(values: dict, tmpl: dict, path: str, robot: str, where: str = "") -> None:
    """Each key of ``values`` is one the reports read (a key of ``tmpl``); where the entries of
    ``tmpl`` are mappings with the same keys (models, tests by name), the names are free and
    their keys checked."""
    shapes = {tuple(sorted(v)) if isinstance(v, dict) else None for v in tmpl.values()}
    named = len(tmpl) > 1 and len(shapes) == 1 and None not in shapes  # entries alike: names
    entry = {}
    if named:
        for v in tmpl.values():
            entry = _merged(entry, v)
    for key, value in values.items():
        at = f"{where}.{key}" if where else key
        sub = entry if named else tmpl.get(key)
        if sub is None:
            raise ConfigError(
                f"{path}: unknown key '{at}' (expected one of: {', '.join(sorted(tmpl))} — the "
                f"values a {robot} campaign's report puts beside its own)"
            )
        if isinstance(value, dict) and isinstance(sub, dict) and sub:
            _check_keys(value, sub, path, robot, at)


def files(campaign: dict) -> list[str]:
    """The reference file a campaign declares (``[]`` when it names a set or none)."""
    declared = campaign.get("reference")
    return [str(declared["file"])] if isinstance(declared, dict) else []


def check(campaign: dict, path: str | Path) -> None:
    """A campaign's ``reference`` names a set of its family, or a valid file of values whose
    keys are those the family's reports read (:func:`template`)."""
    declared = campaign.get("reference")
    if declared is None:
        return
    if isinstance(declared, str):
        known = _named(campaign["robot"])
        if declared not in known:
            raise ConfigError(
                f"{path}: key 'reference': expected one of the reference sets of a "
                f"{campaign['robot']} campaign {sorted(known)} or {{file: <values.yaml>}}, got {declared!r}"
            )
        return
    values = load_file(declared["file"])
    tmpl = template(campaign["robot"])
    if tmpl:
        _check_keys(
            {k: v for k, v in values.items() if k != "source"}, tmpl, declared["file"], campaign["robot"]
        )


def declared(campaign: dict) -> dict:
    """The reference values a campaign declares, with their ``source`` (``{}`` when none)."""
    spec = campaign.get("reference")
    if spec is None:
        return {}
    if isinstance(spec, str):
        from calflow.family import resolve

        target = _named(campaign["robot"]).get(spec)
        if target is None:
            raise ConfigError(
                f"campaign {campaign.get('name')!r}: key 'reference': no reference set {spec!r}"
            )
        return resolve(target)
    return load_file(spec["file"])
