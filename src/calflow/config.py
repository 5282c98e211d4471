"""Loading and validating configuration files against the JSON Schemas.

Every problem is reported as one line naming the file, the key and what was expected.
YAML is loaded with ``yaml.safe_load``; nothing from a configuration is evaluated.
"""

from __future__ import annotations

import copy
import hashlib
import json
import re
from functools import lru_cache
from pathlib import Path
from typing import Any

import jsonschema
import yaml

from calflow.errors import ConfigError
from calflow.family import family_of, resolve, robots

SCHEMA_DIR = Path(__file__).resolve().parent / "schemas"
CAMPAIGN_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]{0,63}$")
_TYPE_NAMES = {"integer": "an integer", "number": "a number", "string": "a string", "array": "a list",
               "object": "a mapping", "boolean": "true or false"}


@lru_cache(maxsize=None)
def schema(name: str) -> dict:
    """The JSON Schema ``workflow/schemas/<name>.schema.yaml``.

    ``campaign-<robot>`` schemas get the keys of ``campaign-common`` merged in.
    """
    sch = yaml.safe_load((SCHEMA_DIR / f"{name}.schema.yaml").read_text())
    if name.startswith("campaign-") and name != "campaign-common":
        common = yaml.safe_load((SCHEMA_DIR / "campaign-common.schema.yaml").read_text())
        sch["properties"] = {**common["properties"], **sch.get("properties", {})}
        sch["$defs"] = {**common.get("$defs", {}), **sch.get("$defs", {})}
        sch["required"] = sorted(set(common.get("required", [])) | set(sch.get("required", [])))
    return sch


def _key(path) -> str:
    return ".".join(str(p) for p in path) or "<top level>"


def _describe(error: jsonschema.ValidationError, file: str) -> str:
    key = _key(error.absolute_path)
    v, s = error.validator, error.schema
    if v == "additionalProperties":
        allowed = sorted(s.get("properties", {}))
        extra = sorted(set(error.instance) - set(allowed))
        where = f"{key}." if error.absolute_path else ""
        expected = f"expected one of: {', '.join(allowed)}" if allowed else "no keys other than the model names"
        return f"{file}: unknown key '{where}{extra[0]}' ({expected})"
    if v == "required":
        missing = error.message.split("'")[1]
        where = f"{key}." if error.absolute_path else ""
        return f"{file}: key '{where}{missing}': missing, it is required"
    if v == "type":
        return f"{file}: key '{key}': expected {_TYPE_NAMES.get(s['type'], s['type'])}, got {error.instance!r}"
    if v == "enum":
        return f"{file}: key '{key}': expected one of {s['enum']}, got {error.instance!r}"
    if v in ("minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum"):
        op = {"minimum": ">=", "maximum": "<=", "exclusiveMinimum": ">", "exclusiveMaximum": "<"}[v]
        return f"{file}: key '{key}': expected a value {op} {s[v]}, got {error.instance!r}"
    if v == "pattern":
        desc = s.get("description", f"text matching {s['pattern']}")
        return f"{file}: key '{key}': expected {desc}, got {error.instance!r}"
    if v in ("minItems", "maxItems", "minProperties"):
        return f"{file}: key '{key}': {error.message}"
    return f"{file}: key '{key}': {error.message}"


def _apply_defaults(node: Any, sch: dict, root: dict) -> Any:
    """Fill in schema defaults of object properties, recursively."""
    if "$ref" in sch:
        ref = sch["$ref"].split("/")[-1]
        sch = {**root["$defs"][ref], **{k: v for k, v in sch.items() if k != "$ref"}}
    if isinstance(node, dict):
        for key, sub in sch.get("properties", {}).items():
            if key not in node and "default" in sub:
                node[key] = copy.deepcopy(sub["default"])
            if key in node:
                node[key] = _apply_defaults(node[key], sub, root)
        extra = sch.get("additionalProperties")
        if isinstance(extra, dict):
            for key in node:
                if key not in sch.get("properties", {}):
                    node[key] = _apply_defaults(node[key], extra, root)
    return node


def load_yaml(path: str | Path) -> Any:
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"{path}: cannot be read ({exc.strerror})") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark else ""
        raise ConfigError(f"{path}: not valid YAML{where} ({getattr(exc, 'problem', exc)})") from None


def validate(data: Any, name: str, file: str | Path) -> dict:
    """Validate ``data`` against schema ``name``; return it with defaults filled in."""
    sch = schema(name)
    if not isinstance(data, dict):
        raise ConfigError(f"{file}: <top level>: expected a mapping of keys, got {type(data).__name__}")
    validator = jsonschema.Draft202012Validator(sch)
    errors = sorted(validator.iter_errors(data), key=lambda e: (len(e.absolute_path), _key(e.absolute_path)))
    if errors:
        raise ConfigError(_describe(errors[0], str(file)))
    return _apply_defaults(copy.deepcopy(data), sch, sch)


def check_campaign_name(name: str) -> str:
    """Return ``name`` if it is a safe campaign name (it names folders under results/ and reports/)."""
    if not isinstance(name, str) or not CAMPAIGN_NAME.match(name):
        raise ConfigError(
            f"campaign name {name!r}: expected letters, digits, '-' or '_' (at most 64), starting with a letter or digit"
        )
    return name




def load_campaign(path: str | Path) -> dict:
    """Load and validate a campaign file; the campaign's name is the file's stem.

    The ``robot`` key chooses the schema (``campaign-<robot>.schema.yaml``).
    """
    path = Path(path)
    check_campaign_name(path.stem)
    data = load_yaml(path)
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: <top level>: expected a mapping of keys, got {type(data).__name__}")
    robot = data.get("robot")
    known = list(robots())
    if robot is None:
        raise ConfigError(f"{path}: key 'robot': missing, it is required (one of {known})")
    if robot not in known:
        raise ConfigError(f"{path}: key 'robot': expected one of {known}, got {robot!r}")
    campaign = validate(data, f"campaign-{robot}", path)
    check = family_of(robot).steps.get("check")
    if check:
        resolve(check)(campaign, path)
    campaign["name"] = path.stem
    return campaign


def load_workflow_config(data: dict, file: str = "config/config.yaml") -> dict:
    """Validate the workflow configuration (already parsed) and return it with defaults."""
    return validate(data, "config", file)


def digest(obj: Any) -> str:
    """SHA-256 of the canonical JSON of ``obj`` (key-sorted)."""
    return hashlib.sha256(json.dumps(obj, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def campaign_digest(campaign: dict) -> str:
    """The ``config_sha256`` attribute of every file a campaign writes."""
    return digest(campaign)
