"""Loading and validating configuration files against the JSON Schemas.

Every problem is reported as one line naming the file, the key and what was expected.
YAML is loaded by :mod:`calflow.configuration.yamlfile` (PyYAML's safe loader, libyaml's when available; aliases
bounded, duplicate keys and look-alike characters refused); nothing from a configuration is evaluated.
"""

from __future__ import annotations

import copy
import datetime as dt
import hashlib
import json
import math
import re
from functools import cache
from pathlib import Path
from typing import Any

import jsonschema
import yaml

from calflow.configuration import yamlfile
from calflow.configuration.reference import check as check_reference
from calflow.configuration.rig_factory import check_rig
from calflow.errors import ConfigError
from calflow.family import family_of, missing_family, robots
from calflow.family import joints as family_joints

SCHEMA_DIR = Path(__file__).resolve().parents[1] / "schemas"
CAMPAIGN_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]{0,63}$")
_TYPE_NAMES = {
    "integer": "an integer",
    "number": "a number",
    "string": "a string",
    "array": "a list",
    "object": "a mapping",
    "boolean": "true or false",
}


# libyaml's safe loader when PyYAML was built with it: the same safe constructors (plain
# data only, nothing evaluated), parsed in C — the pure-Python parser took ~0.3 s of every
# job's start-up on the schemas alone.
_SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def safe_yaml(text: str) -> Any:
    """``yaml.safe_load(text)``, through libyaml when available: for calflow's own files (the
    schemas) and text that is not a configuration file; configuration files go through
    :func:`load_yaml`."""
    return yaml.load(text, Loader=_SAFE_LOADER)


@cache
def schema(name: str) -> dict:
    """The JSON Schema ``workflow/schemas/<name>.schema.yaml``.

    ``campaign-<robot>`` schemas get the keys of ``campaign-common`` merged in; a family
    whose schemas live in its own package says so (:attr:`calflow.family.Family.schemas`).
    """
    sch = safe_yaml(_schema_file(name).read_text())
    if name.startswith("campaign-") and name != "campaign-common":
        common = safe_yaml((SCHEMA_DIR / "campaign-common.schema.yaml").read_text())
        sch["properties"] = {**common["properties"], **sch.get("properties", {})}
        sch["$defs"] = {**common.get("$defs", {}), **sch.get("$defs", {})}
        sch["required"] = sorted(set(common.get("required", [])) | set(sch.get("required", [])))
    return sch


def _schema_file(name: str) -> Path:
    """``<name>.schema.yaml`` in the core's folder, or in the ``schemas/`` folder of the
    package of the family of robot ``<robot>`` for ``campaign-<robot>``."""
    robot = name[len("campaign-") :] if name.startswith("campaign-") else None
    if robot and robot in robots():
        package = family_of(robot).schemas
        if package:
            from importlib.resources import files

            return Path(str(files(package) / "schemas" / f"{name}.schema.yaml"))
    return SCHEMA_DIR / f"{name}.schema.yaml"


def _key(path) -> str:
    return ".".join(str(p) for p in path) or "<top level>"


#: How a pattern of the schemas reads in an error ("expected ...").
_PATTERNS = {
    CAMPAIGN_NAME.pattern: "letters, digits, '-' or '_' (at most 64), starting with a letter or digit",
}


def _pattern_expected(s: dict) -> str:
    return _PATTERNS.get(s["pattern"]) or s.get("description") or f"text matching {s['pattern']}"


def _offending(s: dict, value: object) -> str:
    """``, which contains '/'`` (or ``U+2011 NON-BREAKING HYPHEN``): the first character of
    ``value`` outside the last character class of the pattern, or ``""``."""
    classes = re.findall(r"\[(?:\\.|[^\]])+\]", s["pattern"])
    if not isinstance(value, str) or not classes:
        return ""
    allowed = re.compile(classes[-1])
    for ch in value:
        if not allowed.fullmatch(ch):
            named = repr(ch) if " " < ch <= "~" else yamlfile.char_name(ch)
            return f", which contains {named}"
    return ""


def _describe(error: jsonschema.ValidationError, file: str) -> str:
    key = _key(error.absolute_path)
    v, s = error.validator, error.schema
    if v == "additionalProperties":
        allowed = sorted(s.get("properties", {}))
        extra = sorted(set(error.instance) - set(allowed))
        where = f"{key}." if error.absolute_path else ""
        expected = (
            f"expected one of: {', '.join(allowed)}" if allowed else "no keys other than the model names"
        )
        return f"{file}: unknown key '{where}{extra[0]}' ({expected})"
    if v == "required":
        missing = error.message.split("'")[1]
        where = f"{key}." if error.absolute_path else ""
        return f"{file}: key '{where}{missing}': missing, it is required"
    if v == "type":
        return (
            f"{file}: key '{key}': expected {_TYPE_NAMES.get(s['type'], s['type'])}, got {error.instance!r}"
        )
    if v == "enum":
        odd = yamlfile.describe_odd(error.instance) if isinstance(error.instance, str) else ""
        return f"{file}: key '{key}': expected one of {s['enum']}, got {error.instance!r}{odd}"
    if v in ("minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum"):
        op = {"minimum": ">=", "maximum": "<=", "exclusiveMinimum": ">", "exclusiveMaximum": "<"}[v]
        return f"{file}: key '{key}': expected a value {op} {s[v]}, got {error.instance!r}"
    if v == "pattern":
        return f"{file}: key '{key}': expected {_pattern_expected(s)}, got {error.instance!r}{_offending(s, error.instance)}"
    if v == "range":
        return f"{file}: key '{key}': {error.message}, got {error.instance!r}"
    if v == "format":
        expected = _FORMAT_NAMES.get(s["format"], f"a {s['format']}")
        cause = f" ({error.cause})" if error.cause else ""
        return f"{file}: key '{key}': expected {expected}, got {error.instance!r}{cause}"
    if v in ("minItems", "maxItems", "minProperties"):
        return f"{file}: key '{key}': {error.message}"
    return f"{file}: key '{key}': {error.message}"


def _filling_defaults(properties):
    """jsonschema's ``properties`` keyword, first filling in each absent property's
    ``default`` (a deep copy) — the default-setting validator of jsonschema's FAQ."""

    def validate_properties(validator, props, instance, sch):
        if validator.is_type(instance, "object"):
            for key, sub in props.items():
                if key not in instance and isinstance(sub, dict) and "default" in sub:
                    instance[key] = copy.deepcopy(sub["default"])
        yield from properties(validator, props, instance, sch)

    return validate_properties


def _ordered_ranges(ref):
    """jsonschema's ``$ref`` keyword, and a value of ``$defs/range`` must be ``[low, high]``
    with low < high (an error whose ``validator`` is ``"range"``)."""

    def validate_ref(validator, target, instance, sch):
        if (
            target.endswith("/$defs/range")
            and validator.is_type(instance, "array")
            and len(instance) == 2
            and all(validator.is_type(v, "number") for v in instance)
            and not instance[0] < instance[1]
        ):
            yield jsonschema.ValidationError(
                "expected a range [low, high] with low < high", validator="range"
            )
        yield from ref(validator, target, instance, sch)

    return validate_ref


_Base = jsonschema.Draft202012Validator
#: JSON Schema counts 60.0 and 1e308 (integral floats) as integers: a count, seed or index is
#: written as an integer, and 1e308 poses is not one a rig can visit
_TYPES = _Base.TYPE_CHECKER.redefine(
    "integer", lambda _, value: isinstance(value, int) and not isinstance(value, bool)
)
#: Validates, with ordered ranges; :data:`_Filling` also fills in the schema's defaults.
_Checking = jsonschema.validators.extend(
    _Base, {"$ref": _ordered_ranges(_Base.VALIDATORS["$ref"])}, type_checker=_TYPES
)
_Filling = jsonschema.validators.extend(
    _Checking, {"properties": _filling_defaults(_Base.VALIDATORS["properties"])}
)

#: ``format`` values calflow checks, and how a failure reads ("expected ...").
FORMATS = jsonschema.FormatChecker(formats=())
_FORMAT_NAMES = {"date-time": "a real ISO 8601 date and time"}


@FORMATS.checks("date-time", raises=ValueError)
def _real_date_time(value: object) -> bool:
    """The schema's pattern lets 2026-02-31 through; Python's calendar does not."""
    if isinstance(value, str):
        dt.datetime.fromisoformat(value.replace("Z", "+00:00"))
    return True


def load_yaml(path: str | Path) -> Any:
    """A configuration file's data, through the one loader of configuration files
    (:func:`calflow.configuration.yamlfile.load`: safe, aliases bounded, duplicate keys and look-alike
    characters refused in one line)."""
    return yamlfile.load(path)


def check_finite(node: Any, file: str | Path, path: tuple = ()) -> None:
    """Refuse NaN and ±inf anywhere in a configuration (YAML's ``.nan``, ``.inf``): JSON
    Schema's ``minimum`` lets NaN through. Names the key path."""
    if isinstance(node, float) and not math.isfinite(node):
        raise ConfigError(f"{file}: key '{_key(path)}': expected a finite number, got {node!r}")
    if isinstance(node, dict):
        for k, v in node.items():
            check_finite(v, file, path + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            check_finite(v, file, path + (i,))


def _check_dwells(node: Any, file, path: tuple = ()) -> None:
    """Where a section averages the last seconds of a dwell, they fit in the dwell."""
    if not isinstance(node, dict):
        return
    avg, dwell = node.get("average_last_s"), node.get("dwell_s")
    if isinstance(avg, (int, float)) and isinstance(dwell, (int, float)) and avg > dwell:
        key = _key(path + ("average_last_s",))
        raise ConfigError(
            f"{file}: key '{key}': expected a value <= {_key(path + ('dwell_s',))} ({dwell!r}), got {avg!r}"
        )
    for key, value in node.items():
        _check_dwells(value, file, path + (key,))


def _check_strokes(node: Any, file, path: tuple = ()) -> None:
    """Where a section sweeps from ``start_um`` to ``stop_um``, start lies below stop."""
    if not isinstance(node, dict):
        return
    start, stop = node.get("start_um"), node.get("stop_um")
    if isinstance(start, (int, float)) and isinstance(stop, (int, float)) and not start < stop:
        raise ConfigError(
            f"{file}: key '{_key(path + ('stop_um',))}': expected a value > "
            f"{_key(path + ('start_um',))} ({start!r}), got {stop!r}"
        )
    for key, value in node.items():
        _check_strokes(value, file, path + (key,))


def validate(data: Any, name: str, file: str | Path) -> dict:
    """Validate ``data`` against schema ``name``; return it with defaults filled in."""
    sch = schema(name)
    if not isinstance(data, dict):
        raise ConfigError(f"{file}: <top level>: expected a mapping of keys, got {type(data).__name__}")
    check_finite(data, file)
    # the schema's own errors first, shallowest first; an unordered range only after them
    errors = sorted(
        _Checking(sch, format_checker=FORMATS).iter_errors(data),
        key=lambda e: (e.validator == "range", len(e.absolute_path), _key(e.absolute_path)),
    )
    if errors:
        raise ConfigError(_describe(errors[0], str(file)))
    filled = copy.deepcopy(data)
    for error in _Filling(sch).iter_errors(filled):  # a default the schema itself breaks
        raise ConfigError(
            f"{file}: schema {name}: default of key '{_key(error.absolute_path)}': {error.message}"
        )
    return filled


def check_campaign_name(name: str) -> str:
    """Return ``name`` if it is a safe campaign name (it names folders under results/ and reports/)."""
    if not isinstance(name, str) or not CAMPAIGN_NAME.fullmatch(name):  # "$" alone lets "x\n" in
        raise ConfigError(
            f"campaign name {name!r}: expected letters, digits, '-' or '_' (at most 64), starting with a "
            f"letter or digit{_offending({'pattern': CAMPAIGN_NAME.pattern}, name)}"
        )
    return name


def _check_frame_recordings(campaign: dict, path: Path) -> None:
    """A run recorded as camera frames needs a robot with a joint a camera over a pattern
    measures (x, y, theta). Its files are checked to exist with the replay rig's options
    (:func:`calflow.rigs.replay.check_options`); what they hold (the joints table, the
    pattern file, the camera's field of view on it, the frames) is read and checked by the
    step that decodes them (``calflow decode-run``), never by validation."""
    rig = campaign["rig"]
    recordings = (rig.get("options") or {}).get("recordings")
    if rig["factory"] != "replay" or not isinstance(recordings, dict):
        return
    joints = family_joints(campaign["robot"])
    for run, spec in recordings.items():
        if (
            isinstance(spec, dict)
            and spec.get("format") == "frames"
            and not {"x", "y", "theta"} & set(joints)
        ):
            raise ConfigError(
                f"{path}: key 'rig.options.recordings.{run}': expected a robot with a joint a camera over "
                f"a pattern measures (x, y, theta), got {campaign['robot']!r} (joints {list(joints)})"
            )


def check_campaign_data(data: Any, path: Path, rig_plugins: list[str] | str | None = None) -> dict:
    """A campaign file's data (``path``'s, already parsed) validated, with the defaults filled
    in, as a new dict (``data`` is left as it is); the family's own ``check`` step is
    :func:`calflow.configuration.campaign.load`'s.

    The ``robot`` key chooses the schema (``campaign-<robot>.schema.yaml``). Numbers are
    finite, ranges ordered, ``start`` a real date, averaging windows within their dwell,
    sweeps from ``start_um`` up to ``stop_um``,
    and the rig's options are checked (:func:`calflow.configuration.rig_factory.check_rig`). A
    ``module:callable`` rig factory is checked (allowed, importable, callable) only when
    ``rig_plugins``, the allow-list of plug-in modules, is given; otherwise no plug-in
    code is imported.
    """
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: <top level>: expected a mapping of keys, got {type(data).__name__}")
    robot = data.get("robot")
    known = list(robots())
    if robot is None:
        raise ConfigError(f"{path}: key 'robot': missing, it is required (one of {known})")
    if robot not in known:
        distribution = data.get("distribution")
        raise ConfigError(
            f"{path}: key 'robot': {missing_family(str(robot), distribution)}"
            if isinstance(distribution, str) and distribution
            else f"{path}: key 'robot': expected one of {known}, got {robot!r}"
        )
    campaign = validate(data, f"campaign-{robot}", path)
    _check_dwells(campaign, path)
    _check_strokes(campaign, path)
    check_rig(campaign, path, rig_plugins, plugins=rig_plugins is not None)
    _check_frame_recordings(campaign, path)
    check_reference(campaign, path)
    return campaign


def load_workflow_config(data: dict, file: str = "config/config.yaml") -> dict:
    """Validate the workflow configuration (already parsed) and return it with defaults."""
    return validate(data, "config", file)


def digest(obj: Any) -> str:
    """SHA-256 of the canonical JSON of ``obj`` (key-sorted)."""
    return hashlib.sha256(json.dumps(obj, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def campaign_digest(campaign: dict) -> str:
    """The ``config_sha256`` attribute of every file a campaign writes: the campaign without its
    ``reference`` (the published values a report puts beside the results change no data file)."""
    return digest({k: v for k, v in campaign.items() if k != "reference"})
