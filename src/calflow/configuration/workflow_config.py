"""The workflow configuration as Snakemake hands it over, checked before any job.

Snakemake reads ``config/config.yaml`` (and ``--configfile`` files) itself and parses
``--config KEY=VALUE``: a top-level value as a number or true/false when it reads as one,
a nested one (``--config 'stages={"SN-0042": {"tolerance_um": 3}}'``) as text all the way
down. :func:`load` reads the files again through calflow's configuration loader
(:mod:`calflow.configuration.yamlfile`: duplicate keys, look-alike characters and alias bombs refused),
gives each command-line value the type the schema asks for (a YAML scalar, parsed safely),
and validates the result (:func:`calflow.configuration.config.load_workflow_config`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from calflow.configuration.config import load_workflow_config, load_yaml, schema
from calflow.configuration.yamlfile import parse
from calflow.errors import ConfigError

#: How the command line is named in an error about a value it gave.
COMMAND_LINE = "--config"


def _types(sch: Mapping) -> set[str]:
    t = sch.get("type", ())
    return {t} if isinstance(t, str) else set(t)


def typed(value: Any, sch: Mapping | None) -> Any:
    """``value`` (from ``--config``) with each text leaf that the schema ``sch`` wants as a
    number, an integer, true/false or null parsed as a YAML scalar (safely: plain data only);
    other text, and text that does not parse as such a scalar, stays as it is."""
    sch = sch if isinstance(sch, Mapping) else {}
    if isinstance(value, dict):
        props = sch.get("properties", {})
        extra = sch.get("additionalProperties")
        return {
            k: typed(v, props.get(k, extra if isinstance(extra, Mapping) else None)) for k, v in value.items()
        }
    if isinstance(value, list):
        return [typed(v, sch.get("items")) for v in value]
    wanted = _types(sch)
    if isinstance(value, str) and wanted and "string" not in wanted:
        try:
            parsed = parse(value, COMMAND_LINE)  # as in a file: 1e-3 is a number
        except ConfigError:
            return value
        if parsed is None or isinstance(parsed, (bool, int, float)):
            return parsed
    return value


def _merge(base: dict, extra: Mapping) -> dict:
    """``base`` updated recursively with ``extra`` (Snakemake's ``update_config``)."""
    out = dict(base)
    for k, v in extra.items():
        out[k] = _merge(out[k], v) if isinstance(v, Mapping) and isinstance(out.get(k), dict) else v
    return out


def load(config: Mapping, files: Iterable[str | Path] = (), overrides: Mapping | None = None) -> dict:
    """The checked workflow configuration from Snakemake's ``config`` (the files' data and
    the command line's merged), its configuration ``files`` and the command line's
    ``overrides``. Raises :class:`~calflow.errors.ConfigError` in one line."""
    files = [str(f) for f in files]
    data: dict = {}
    for f in files:  # the files as calflow reads them (1e-3 a number), not as Snakemake's loader did
        loaded = load_yaml(f)
        data = _merge(data, loaded) if isinstance(loaded, dict) else data
    overrides = dict(overrides or {})
    data = _merge(data if files else dict(config), typed(overrides, schema("config")))
    name = files[-1] if files else "config/config.yaml"
    if overrides:
        name = f"{name} (with {COMMAND_LINE} {', '.join(sorted(overrides))})"
    return load_workflow_config(data, name)
