"""The one YAML loader of calflow's configuration files (workflow config, campaigns, studies,
reference values): safe, bounded and strict about what a person cannot see.

PyYAML's safe loader (libyaml's when available) builds plain data only; nothing is evaluated.
On top of it, a document is refused — one line naming the file, the line and the key — when

* its aliases would expand it beyond :data:`MAX_NODES` values (the "billion laughs": a 1 KB
  file of nested aliases stands for 10⁹ values), or an alias refers to itself; otherwise
  aliases are expanded into independent copies, so an edit of one never shows in another;
* a mapping has the same key twice (YAML says keys are unique; PyYAML keeps the last one
  silently, so a second ``stage:`` line would file the campaign under the other stage);
* a key holds a character other than printable ASCII (every calflow key is), or any value
  holds an invisible or unusual space (no-break space, zero width space, bidirectional
  controls, ...) or a letter of another script inside a Latin word (the Cyrillic а in
  ``simulаted``): "contains U+0430 CYRILLIC SMALL LETTER A". Free text (the values of
  :data:`TEXT_KEYS`) may hold any printable character of any script and ordinary spaces.
"""

from __future__ import annotations

import re
import unicodedata
from pathlib import Path
from typing import Any

import yaml

from calflow.errors import ConfigError

#: At most this many values (scalars, lists and mappings) once aliases are expanded; calflow's
#: largest shipped file holds a few hundred. A file over it is refused before it is built.
MAX_NODES = 200_000
#: Keys whose values are free text (a description, a publication's citation).
TEXT_KEYS = frozenset({"description", "source"})

_BASE = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_ALLOWED_CONTROLS = {"\t", "\n", "\r"}


def char_name(ch: str) -> str:
    """``U+0430 CYRILLIC SMALL LETTER A``: a character as Unicode names it (a control
    character, which Unicode leaves unnamed, by its category)."""
    if unicodedata.category(ch) == "Cc":
        return f"U+{ord(ch):04X} CONTROL CHARACTER {_CONTROLS.get(ch, '')}".rstrip()
    return f"U+{ord(ch):04X} {unicodedata.name(ch, 'UNNAMED CHARACTER')}"


_CONTROLS = {"\t": "(TAB)", "\n": "(LINE FEED)", "\r": "(CARRIAGE RETURN)", "\x00": "(NULL)"}


def shown(text: str) -> str:
    """``text`` as an error line may show it: characters one cannot see, line breaks among
    them, escaped (``a\\nb``), so that a message stays one line."""
    return "".join(
        ch if ch == " " or unicodedata.category(ch)[0] not in "CZ" else ch.encode("unicode_escape").decode()
        for ch in text
    )


def _dotted(path) -> str:
    return shown(".".join(path)) or "<top level>"


def _invisible(ch: str) -> bool:
    """A character one cannot see or tell from a space: spaces other than U+0020, format
    characters (zero width, bidirectional controls, soft hyphen), line and paragraph
    separators, control characters other than tab and newline."""
    if ch == " " or ch in _ALLOWED_CONTROLS:
        return False
    return unicodedata.category(ch) in ("Zs", "Zl", "Zp", "Cf", "Cc", "Co", "Cs", "Cn")


def _script(ch: str) -> str:
    """The script of a letter, from its Unicode name's first word (LATIN, CYRILLIC, GREEK …)."""
    return unicodedata.name(ch, "UNKNOWN").split(" ", 1)[0]


def odd_character(text: str, key: bool = False, free_text: bool = False) -> str | None:
    """The first character of ``text`` a reader cannot tell apart from another, or None.

    In a key (``key``): anything but printable ASCII. In free text: invisible characters
    only. In any other value: invisible characters, and a non-Latin letter in a word that has
    Latin letters (a look-alike: ``SN‑0042`` keeps its dash for the value's own check)."""
    for ch in text:
        if _invisible(ch):
            return ch
        if key and not (" " <= ch <= "~"):
            return ch
    if key or free_text:
        return None
    for word in "".join(c if c.isalnum() else " " for c in text).split():
        scripts = {_script(c) for c in word if c.isalpha()}
        if "LATIN" in scripts and len(scripts) > 1:
            return next(c for c in word if c.isalpha() and _script(c) != "LATIN")
    return None


def _expected(ch: str, key: bool) -> str:
    """What was expected instead of the odd character ``ch``."""
    if _invisible(ch):
        return "expected ordinary spaces (U+0020) and visible characters"
    if key:
        return "expected a key of plain ASCII characters (a look-alike?)"
    return f"expected one script within a word, not Latin mixed with {_script(ch).title()} (a look-alike letter?)"


def describe_odd(text: str) -> str:
    """``, which contains U+2013 EN DASH`` for each character of ``text`` outside printable
    ASCII (the first three), or ``""``: what an error message adds about a look-alike."""
    odd = list(dict.fromkeys(ch for ch in text if not (" " <= ch <= "~")))[:3]
    return f", which contains {', '.join(char_name(c) for c in odd)}" if odd else ""


class _Refused(Exception):
    def __init__(self, message: str, node: yaml.Node | None = None):
        super().__init__(message)
        self.line = node.start_mark.line + 1 if node is not None and node.start_mark else None


def _key_text(node: yaml.Node) -> str:
    return str(node.value) if isinstance(node, yaml.ScalarNode) else f"<{node.tag.rsplit(':', 1)[-1]}>"


def _check_tree(root: yaml.Node) -> None:
    """Walk the composed document once: aliases (a node met again) counted by the size they
    expand to, recursive ones refused; duplicate keys and odd characters refused."""
    sizes: dict[int, int] = {}
    open_nodes: set[int] = set()

    def walk(node: yaml.Node, path: tuple[str, ...], free: bool) -> int:
        ident = id(node)
        if ident in sizes:  # an alias of a node already walked: its size, nothing new to check
            return sizes[ident]
        if ident in open_nodes:
            raise _Refused(f"key '{_dotted(path)}': an alias that refers to itself", node)
        open_nodes.add(ident)
        size = 1
        if isinstance(node, yaml.ScalarNode):
            odd = odd_character(str(node.value), free_text=free)
            if odd is not None:
                raise _Refused(
                    f"key '{_dotted(path)}': value {node.value!r} contains "
                    f"{char_name(odd)}; {_expected(odd, False)}",
                    node,
                )
        elif isinstance(node, yaml.SequenceNode):
            for i, item in enumerate(node.value):
                size += walk(item, (*path, str(i)), free)
        elif isinstance(node, yaml.MappingNode):
            seen: dict[Any, yaml.Node] = {}
            for key_node, value_node in node.value:
                name = _key_text(key_node)
                if isinstance(key_node, yaml.ScalarNode):
                    if key_node.tag == "tag:yaml.org,2002:merge":
                        size += walk(value_node, path, free)
                        continue
                    odd = odd_character(name, key=True)
                    if odd is not None:
                        where = _dotted((*path, name))
                        raise _Refused(
                            f"key '{where}' contains {char_name(odd)}; {_expected(odd, True)}", key_node
                        )
                    ident_key = (key_node.tag, key_node.value)
                    if ident_key in seen:
                        first = seen[ident_key].start_mark.line + 1
                        raise _Refused(
                            f"key '{_dotted((*path, name))}' appears twice (first at line {first}): "
                            "expected each key once",
                            key_node,
                        )
                    seen[ident_key] = key_node
                size += 1 + walk(value_node, (*path, name), name in TEXT_KEYS)
        open_nodes.discard(ident)
        sizes[ident] = size
        if size > MAX_NODES:
            raise _Refused(
                f"key '{_dotted(path)}': its aliases expand to more than "
                f"{MAX_NODES} values; expected a configuration written out (anchors and aliases "
                "only for small repeated sections)",
                node,
            )
        return size

    walk(root, (), False)


def _unshared(value: Any) -> Any:
    """A copy in which no list or mapping appears twice (an alias becomes its own copy)."""
    if isinstance(value, dict):
        return {k: _unshared(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_unshared(v) for v in value]
    return value


class _Loader(_BASE):  # type: ignore[misc, valid-type]
    """The safe loader, with :func:`_check_tree` between composing and building."""

    def construct_document(self, node):
        _check_tree(node)
        return super().construct_document(node)


# YAML 1.2's floats with an exponent (1e-3, 1e308, 2.5E3): YAML 1.1, PyYAML's, reads them as
# text unless they have a dot and a signed exponent, so a tolerance of 1e-3 was the string
# '1e-3' and a count of 1e308 was refused as "not an integer, got '1e308'"
_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."),
)


def parse(text: str, file: str | Path, what: str = "") -> Any:
    """The data of the YAML document ``text`` read from ``file`` (named in errors, after it
    ``what`` the file is, e.g. "reference file"), checked as the module says. Raises
    :class:`ConfigError` in one line."""
    file = f"{file}: {what}" if what else str(file)
    loader = _Loader(text)
    try:
        data = loader.get_single_data()
    except _Refused as exc:
        at = f" line {exc.line}:" if exc.line else ""
        raise ConfigError(f"{file}:{at} {exc}") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" line {mark.line + 1}:" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ConfigError(f"{file}:{where} not valid YAML ({problem})") from None
    except RecursionError:
        raise ConfigError(f"{file}: not valid YAML (nested too deeply)") from None
    finally:
        loader.dispose()
    return _unshared(data)


def load(path: str | Path, what: str = "") -> Any:
    """The data of the YAML file ``path`` (:func:`parse`); ``what`` (e.g. "reference file")
    prefixes the reason a file cannot be read."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(
            f"{path}: {what + ': ' if what else ''}expected UTF-8 text ({exc.reason} at byte {exc.start})"
        ) from None
    except OSError as exc:
        raise ConfigError(
            f"{path}: {what + ': ' if what else ''}cannot be read ({exc.strerror or exc})"
        ) from None
    return parse(text, path, what)
