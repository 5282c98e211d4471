"""A campaign: its file parsed and validated once per process, immutable, with what its
validation resolves as fields of its own.

:func:`load` reads ``config/campaigns/<name>.yaml`` (the one YAML loader,
:mod:`calflow.configuration.yamlfile`), validates it against its robot's schema with the defaults filled
in, runs the checks beyond the schema (:mod:`calflow.configuration.config`, the rig's options, the
published reference values, the family's ``check`` step) and returns a :class:`Campaign`.
The family's check changes nothing: it returns what it resolves (:class:`Resolution`: the
rig's options as the stage has aged by the campaign's start, an interim check's models,
workspace and runs, the campaign it checks), and the campaign keeps it beside the sections
the file gives.

Loading is cached by the file's path and the SHA-256 of its bytes: every entry point of a job
(the command, the plans, the checks, an interim check's reference) gets the same object, the
file parsed once; an edited file is parsed again. :data:`PARSES` counts the parses by path.

A :class:`Campaign` is a read-only mapping of its sections (``c["rig"]["options"]``), deep:
every mapping in it is a :class:`FrozenDict` and every list a :class:`FrozenList`, whose
mutating methods raise ``TypeError``. ``copy.deepcopy`` gives a plain, mutable copy (for a
variant of the campaign, e.g. a study's); so does :func:`thaw`.
"""

from __future__ import annotations

import hashlib
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from calflow.configuration.config import check_campaign_data, check_campaign_name, digest
from calflow.errors import CalflowError, ConfigError
from calflow.step import Job

#: YAML parses of campaign files in this process, by resolved path (a test counts them).
PARSES: Counter[str] = Counter()


def _refuse(self, *args, **kwargs):
    raise TypeError(f"a campaign is immutable: {type(self).__name__} cannot be changed (copy.deepcopy it)")


class FrozenDict(dict):
    """A ``dict`` whose mutating methods raise ``TypeError`` (JSON and ``isinstance(x, dict)``
    see a dict; ``copy.deepcopy`` returns a plain, mutable one)."""

    __slots__ = ()
    __setitem__ = __delitem__ = __ior__ = _refuse
    clear = pop = popitem = setdefault = update = _refuse

    def __copy__(self) -> dict:
        return dict(self)

    def __deepcopy__(self, memo) -> dict:
        return thaw(self)

    def __reduce__(self):
        return (FrozenDict, (dict(self),))

    def __hash__(self):  # type: ignore[override]
        raise TypeError("unhashable type: 'FrozenDict'")


class FrozenList(list):
    """A ``list`` whose mutating methods raise ``TypeError``."""

    __slots__ = ()
    __setitem__ = __delitem__ = __iadd__ = __imul__ = _refuse
    append = extend = insert = pop = remove = clear = sort = reverse = _refuse

    def __copy__(self) -> list:
        return list(self)

    def __deepcopy__(self, memo) -> list:
        return thaw(self)

    def __reduce__(self):
        return (FrozenList, (list(self),))


def dig(data: Any, key: str | tuple[str, ...]) -> Any:
    """``data["a"]["b"]…`` for the dotted ``key = "a.b…"`` (or the tuple of its parts), through
    mappings and, by index, lists; None when any part is missing. calflow's one walker of a
    dotted path: a campaign's sections (:meth:`Campaign.part`), a summary's figures (the
    reports, the certificate)."""
    for part in key.split(".") if isinstance(key, str) else key:
        if isinstance(data, Mapping) and part in data:
            data = data[part]
        elif isinstance(data, list) and part.isdigit() and int(part) < len(data):
            data = data[int(part)]
        else:
            return None
    return data


def freeze(value: Any) -> Any:
    """``value`` with every mapping a :class:`FrozenDict` and every list a :class:`FrozenList`."""
    if isinstance(value, Mapping):
        return FrozenDict((k, freeze(v)) for k, v in value.items())
    if isinstance(value, (list, tuple)):
        return FrozenList(freeze(v) for v in value)
    return value


def thaw(value: Any) -> Any:
    """A plain, mutable copy of ``value`` (dicts and lists all the way down)."""
    if isinstance(value, Mapping):
        return {k: thaw(v) for k, v in value.items()}
    if isinstance(value, list):
        return [thaw(v) for v in value]
    return value


def _read(path: Path) -> tuple[str, str]:
    """The file's text and the SHA-256 of its bytes (errors as :func:`calflow.configuration.yamlfile.load`'s)."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ConfigError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: expected UTF-8 text ({exc.reason} at byte {exc.start})") from None
    return text, hashlib.sha256(data).hexdigest()


_RAW: dict[tuple[str, str], Any] = {}
_LOADED: dict[tuple[str, str, tuple[str, ...] | None], Campaign] = {}


def _parsed(path: Path) -> tuple[Any, str]:
    """The file's data (frozen) and digest, parsed once per content."""
    from calflow.configuration import yamlfile

    text, sha = _read(path)
    key = (str(path.resolve()), sha)
    if key not in _RAW:
        PARSES[key[0]] += 1
        _RAW[key] = freeze(yamlfile.parse(text, path))
    return _RAW[key], sha


def raw(path: str | Path) -> Any:
    """A campaign file's data as written, unvalidated and frozen (for what reads another
    run's campaigns, which may not validate): parsed once per content, as :func:`load`'s."""
    return _parsed(Path(path))[0]


@dataclass(frozen=True)
class Interim:
    """What an interim check's validation resolves from the calibration it checks."""

    reference: str  #: the campaign it checks (``interim_check.reference``)
    model: str  #: the reference's model whose exported bundle it checks
    dwell_s: float  #: dwell at each visit, s (the reference's validation dwell unless given)
    workspace: Mapping[str, Any]  #: the reference's identification workspace (x_um, y_um, theta_deg)
    runs: tuple[str, ...]  #: every run file of the reference (its rig time)

    def __post_init__(self):
        object.__setattr__(self, "workspace", freeze(self.workspace))
        object.__setattr__(self, "runs", tuple(self.runs))


@dataclass(frozen=True)
class Resolution:
    """What a family's ``check`` step resolves (it returns one, or None for nothing)."""

    #: the ``rig`` section with its options as the stage has aged by the campaign's start
    rig: Mapping[str, Any] | None = None
    #: the models, when the file gives none (an interim check identifies none: ``{}``)
    models: Mapping[str, Any] | None = None
    #: an interim check's resolution
    interim: Interim | None = None
    #: the campaign whose results this one reads (an interim check's reference)
    reference: Campaign | None = None

    def __post_init__(self):
        for name in ("rig", "models"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, freeze(getattr(self, name)))


class Campaign(FrozenDict):
    """A validated campaign: a read-only mapping of its sections as resolved (the families'
    view, with ``name``), and typed fields.

    ``sections`` are what the file gives with the schema's defaults; ``rig`` the rig section
    as resolved (options aged); ``models`` the models it identifies; ``interim`` and
    ``reference`` what an interim check resolves (else None); ``sha256`` the file's digest.
    """

    __slots__ = ("name", "path", "sha256", "sections", "resolution")

    def __init__(self, name: str, path: Path, sha256: str, sections: Mapping, resolution: Resolution):
        view = dict(sections)
        if resolution.rig is not None:
            view["rig"] = resolution.rig
        if resolution.models is not None:
            view["models"] = resolution.models
        if resolution.interim is not None:
            i = resolution.interim
            section = {**sections["interim_check"], "dwell_s": i.dwell_s}
            section["resolved"] = {"workspace": i.workspace, "runs": list(i.runs)}
            view["interim_check"] = section
        view["name"] = name
        dict.__init__(self, freeze(view))
        for attr, value in (
            ("name", name),
            ("path", path),
            ("sha256", sha256),
            ("sections", freeze(sections)),
            ("resolution", resolution),
        ):
            object.__setattr__(self, attr, value)

    def __setattr__(self, name, value):
        _refuse(self)

    __delattr__ = __setattr__

    def __reduce__(self):
        return (_unpickle, (str(self.path), self.sha256))

    @property
    def robot(self) -> str:
        return self["robot"]

    @property
    def rig(self) -> Mapping[str, Any]:
        return self["rig"]

    @property
    def models(self) -> Mapping[str, Any]:
        return self.get("models", FrozenDict())

    @property
    def interim(self) -> Interim | None:
        return self.resolution.interim

    @property
    def reference(self) -> Campaign | None:
        return self.resolution.reference

    def part(self, key: str) -> Any:
        """Section ``key`` as resolved, or a key within it (``"validation.heldout"``, at any depth,
        as :meth:`only` hands it); None when absent."""
        return dig(self, key)

    def digest(self, keys) -> str:
        """SHA-256 of the sections ``keys`` (as resolved, :meth:`part`; None for an absent one):
        the rerun digest of a step that reads these sections."""
        return digest([self.part(k) for k in keys])

    def only(self, keys, step: str = "this step") -> Sections:
        """The campaign as a step that reads only the sections ``keys`` sees it (its rule
        hands it those and digests the same, :meth:`digest`): reading another section raises
        :class:`SectionNotHanded`, so a step cannot read what its rerun digest misses. A key
        ``"section.key"`` hands that one key of a section (the others of it are not handed)."""
        return Sections(self, tuple(keys), step)


class SectionNotHanded(CalflowError, KeyError):
    """A step read a campaign section its rule does not hand it (nor digest): a ``KeyError``
    (a missing key of the mapping), reported as one line as every calflow error is."""

    def __str__(self) -> str:  # KeyError's own quotes the message
        return str(self.args[0]) if self.args else ""


class Sections(FrozenDict):
    """The sections of a campaign its rule hands a step (:meth:`Campaign.only`), and ``name``;
    a section of which only some keys are handed is a :class:`Sections` of those keys."""

    __slots__ = ("handed", "step", "campaign", "names", "prefix")

    def __init__(self, campaign: Campaign, keys: tuple[str, ...], step: str, _of=None, _prefix: str = ""):
        whole = {k for k in keys if "." not in k}
        parts: dict[str, list[str]] = {}
        for k in keys:
            head, _, sub = k.partition(".")
            if sub and head not in whole:
                parts.setdefault(head, []).append(sub)
        source = campaign if _of is None else _of
        items = {}
        for k, v in source.items():
            if k in whole or (k == "name" and _of is None):
                items[k] = v
            elif k in parts and isinstance(v, Mapping):
                items[k] = Sections(campaign, tuple(parts[k]), step, v, f"{_prefix}{k}.")
        handed = frozenset(whole | set(parts) | ({"name"} if _of is None else set()))
        dict.__init__(self, items)
        for attr, value in (
            ("handed", handed),
            ("step", step),
            ("campaign", campaign),
            ("names", tuple(keys)),
            ("prefix", _prefix),
        ):
            object.__setattr__(self, attr, value)

    def _check(self, key) -> None:
        if key not in self.handed:
            given = sorted(f"{self.prefix}{k}" for k in self.names)
            raise SectionNotHanded(
                f"{self.campaign.path}: {self.step} read section {self.prefix + str(key)!r}, which its rule does "
                f"not hand it (it hands {', '.join(given) or 'none'}): add it to the rule's sections"
            )

    def __getitem__(self, key):
        self._check(key)
        return dict.__getitem__(self, key)

    def get(self, key, default=None):
        self._check(key)
        return dict.get(self, key, default)

    def __contains__(self, key) -> bool:
        self._check(key)
        return dict.__contains__(self, key)

    def __setattr__(self, name, value):
        _refuse(self)

    def __reduce__(self):
        if self.prefix:  # a part of a section: a plain copy of what it holds
            return (FrozenDict, (dict(self),))
        return (_sections, (self.campaign, self.names, self.step))


def _sections(campaign: Campaign, keys: tuple[str, ...], step: str) -> Sections:
    return Sections(campaign, keys, step)


def _unpickle(path: str, sha256: str) -> Campaign:
    c = load(path)
    if c.sha256 != sha256:
        raise ConfigError(f"{path}: changed since the campaign was loaded")
    return c


def load(path: str | Path, rig_plugins: list[str] | str | None = None) -> Campaign:
    """The campaign of file ``path``, validated (its name is the file's stem); cached by path,
    content and ``rig_plugins``.

    The ``robot`` key chooses the schema; :func:`calflow.configuration.config.check_campaign_data` checks
    what it does beyond it. A ``module:callable`` rig factory is checked (allowed,
    importable, callable) only when ``rig_plugins``, the allow-list of plug-in modules, is
    given; otherwise no plug-in code is imported. Raises :class:`ConfigError` in one line.
    """
    from calflow.configuration.rig_factory import builtin
    from calflow.family import family_of, resolve

    path = Path(path)
    check_campaign_name(path.stem)
    data, sha = _parsed(path)
    plugins = (
        None if rig_plugins is None else tuple([rig_plugins] if isinstance(rig_plugins, str) else rig_plugins)
    )
    rig = data.get("rig") if isinstance(data, Mapping) else None
    if isinstance(rig, Mapping) and builtin(str(rig.get("factory")), str(data.get("robot"))) is not None:
        plugins = None  # a built-in rig is checked alike with or without the plug-ins' allow-list
    key = (str(path.resolve()), sha, plugins)
    if key in _LOADED:
        return _LOADED[key]
    sections = freeze(check_campaign_data(thaw(data), path, rig_plugins))
    check = family_of(sections["robot"]).steps.get("check")
    resolution = (resolve(check)(sections, Job.of("check", campaign=path)) if check else None) or Resolution()
    if not isinstance(resolution, Resolution):
        raise TypeError(
            f"{check}: expected a calflow.configuration.campaign.Resolution or None, got {type(resolution).__name__}"
        )
    campaign = Campaign(path.stem, path, sha, sections, resolution)
    _LOADED[key] = campaign
    return campaign
