"""docs/api.md is the public API: every name it lists imports, with the signature it shows,
and every old path it keeps still imports and warns, naming the new one."""

from __future__ import annotations

import importlib
import inspect
import re
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from calflow.moved import MOVED

DOC = Path(__file__).resolve().parents[2] / "docs" / "api.md"
ROW = re.compile(r"^\| `(calflow[\w.]*)` \| `(.*?)` \|", re.M)
MOVED_ROW = re.compile(r"^\| `(calflow[\w.]*)` \| `(calflow[\w.]*)` \|$", re.M)


def _rows():
    text = DOC.read_text()
    return [
        (name, sig.replace("\\|", "|"))
        for name, sig in ROW.findall(text)
        if not MOVED_ROW.match(f"| `{name}` | `{sig}` |")
    ]


def _object(dotted: str):
    module, _, attr = dotted.rpartition(".")
    return getattr(importlib.import_module(module), attr)


def signature_text(obj) -> str:
    """The signature as docs/api.md writes it: annotations as written, defaults as repr."""
    if getattr(obj, "_is_protocol", False):
        members = list(obj.__dict__.get("__annotations__", {}))
        members += [n for n, v in vars(obj).items() if callable(v) and not n.startswith("_")]
        return "protocol: " + ", ".join(members)
    sig = inspect.signature(obj)

    def ann(a):
        return a if isinstance(a, str) else inspect.formatannotation(a)

    parts, star = [], False
    for p in sig.parameters.values():
        if p.kind is p.KEYWORD_ONLY and not star:
            parts.append("*")
            star = True
        text = {p.VAR_POSITIONAL: "*", p.VAR_KEYWORD: "**"}.get(p.kind, "") + p.name
        star = star or p.kind is p.VAR_POSITIONAL
        if p.annotation is not p.empty:
            text += f": {ann(p.annotation)}"
        if p.default is not p.empty:
            text += f" = {p.default!r}" if p.annotation is not p.empty else f"={p.default!r}"
        parts.append(text)
    out = f"({', '.join(parts)})"
    if sig.return_annotation is not sig.empty and sig.return_annotation not in ("None", None):
        out += f" -> {ann(sig.return_annotation)}"
    return out


def test_the_page_lists_names():
    assert len(_rows()) >= 20


@pytest.mark.parametrize("name,signature", _rows(), ids=[n for n, _ in _rows()])
def test_every_public_name_imports_with_its_signature(name, signature):
    obj = _object(name)
    assert signature_text(obj) == signature, (
        f"docs/api.md shows {name}{signature}; the code has {signature_text(obj)}"
    )
    assert inspect.getdoc(obj), f"{name} has no docstring"


def test_the_moved_table_is_the_one_calflow_serves():
    assert dict(MOVED_ROW.findall(DOC.read_text())) == MOVED


@pytest.mark.parametrize("old,new", sorted(MOVED.items()))
def test_an_old_path_gives_the_new_names_with_a_warning(old, new):
    target = importlib.import_module(new)
    names = getattr(target, "__all__", None) or [n for n in vars(target) if not n.startswith("_")]
    name = sorted(names)[0]
    stand_in = importlib.import_module(old)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        value = getattr(stand_in, name)
    assert value is getattr(target, name)
    assert [w.category for w in caught] == [DeprecationWarning]
    assert new in str(caught[0].message) and old in str(caught[0].message)
    with pytest.raises(AttributeError):
        stand_in.no_such_name_anywhere  # noqa: B018


@pytest.mark.process  # a user's script in a fresh interpreter
def test_the_two_documented_paths_users_called_warn_at_their_line():
    """`from calflow.stepwise import stepwisefit` in a user's script: the warning points at the
    script's line (so Python shows it there by default) and the function still works."""
    script = (
        "import warnings; warnings.simplefilter('error', DeprecationWarning)\n"
        "try:\n"
        "    from calflow.stepwise import stepwisefit\n"
        "except DeprecationWarning as e:\n"
        "    print('warned', e)\n"
        "warnings.simplefilter('ignore')\n"
        "from calflow.stepwise import stepwisefit\n"
        "from calflow.uncertainty import interferometer_budget\n"
        "import numpy as np\n"
        "X = np.random.default_rng(0).normal(size=(40, 3)); y = 2 * X[:, 0] + 0.01 * X[:, 2]\n"
        "print(stepwisefit(X, y).inmodel.tolist(), interferometer_budget().combined_nm > 0)\n"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout
    assert "warned calflow.stepwise moved to calflow.identification.stepwise" in out
    assert out.strip().endswith("True")
    assert "[True, False" in out
