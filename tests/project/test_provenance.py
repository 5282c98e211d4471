"""Rerun digests derived from the code (calflow.provenance): each ``calflow`` command's digest
covers every calflow and family module it imports, a comment or docstring changes none, and
a code change reruns exactly the steps that reach the changed module."""

from __future__ import annotations

import ast
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from conftest import ROOT, snakemake

from calflow.cli import entry_point, entry_points
from calflow.family import families
from calflow.provenance import FAMILY_HOOKS, closure
from calflow.provenance.modules import family_packages, scan


def _commands() -> list[tuple[str, str | None]]:
    """(command, robot) of every digest the workflow's rules ask for."""
    core = ("acquire", "identify", "metrics", "summarise", "report", "history", "history-report")
    pairs = [
        (c, r) for fam in families() for r in fam.robots for c in core + tuple(x.name for x in fam.commands)
    ]
    return [*pairs, ("index", None)]


# ---------------------------------------------------------------------------- the scanner


def test_scan_finds_every_kind_of_import_and_no_docstring():
    code = '''
"""Module docstring naming calflow.fake:thing, which is no import."""
import calflow.a.b
from . import sibling
from .. import uncle
from .sub import name
from calflow.top import *

TABLE = {"x": "calflow.looked.up:target"}


def f():
    """calflow.doc:string is no import either."""
    import calflow.inside
    from calflow.deep import helper
    importlib.import_module("calflow.dynamic")
    return g()


@decorate(default=calflow_default)
def g(x=DEFAULT):
    return helper()
'''
    scanned = scan(ast.parse(code), "calflow.pkg.mod", False, True)
    top, _ = scanned[""]
    assert ["calflow.a.b", None] in top and ["calflow.pkg", "sibling"] in top and ["calflow", "uncle"] in top
    assert ["calflow.pkg.sub", "name"] in top and ["calflow.top", None] in top
    assert scanned["TABLE"][0] == [["calflow.looked.up", "target"]]  # followed where TABLE is read
    assert {"decorate", "calflow_default", "DEFAULT"} <= set(scanned[""][1])  # run on import
    imports, names = scanned["f"]
    assert sorted(imports) == [
        ["calflow.deep", "helper"],
        ["calflow.dynamic", None],
        ["calflow.inside", None],
    ]
    assert "g" in names
    everything = json.dumps(scanned)
    assert "calflow.fake" not in everything and "calflow.doc" not in everything


def test_every_core_look_up_of_a_family_hook_is_declared():
    """A core module that resolves a family's ``"module:attribute"`` (an import no import
    statement shows) must say which hooks in FAMILY_HOOKS, or its digests would miss them."""
    core = ROOT / "src" / "calflow"
    # (a Path's .resolve() is no look-up)
    lookups = re.compile(r"(?<!\.)\bresolve\(|\.step\([\"']|\.plan\(|import_module\(|files\(family\.")
    found = set()
    for path in core.rglob("*.py"):
        module = ".".join(path.relative_to(core.parent).with_suffix("").parts).removesuffix(".__init__")
        if module.split(".")[1:2] in (["xytheta"], ["nano"]) or not lookups.search(path.read_text()):
            continue
        found.add(module)
    # calflow.family and its contract check (family_contract, hook_source) resolve what they
    # are given; calflow.provenance only names the look-ups; calflow.moved imports the new home
    # of an old path a user's script names (no step imports an old path); calflow.cli resolves
    # the function of the step it runs (where that step's closure starts)
    declared = {k.partition(":")[0] for k in FAMILY_HOOKS} | {
        "calflow.cli",
        "calflow.moved",
        "calflow.family",
        "calflow.family_contract",
        "calflow.hook_source",
        "calflow.provenance",
        "calflow.provenance.modules",
    }
    assert found - declared == set()


def test_closures_stay_inside_calflow_and_the_families():
    tops = set(family_packages())
    assert "calflow_hexapod" in tops
    for command, robot in _commands():
        modules = closure(entry_point(command), robot)
        assert {m.split(".")[0] for m in modules} <= tops
        assert entry_point(command).partition(":")[0] in modules and "calflow.cli" in modules


# ---------------------------------------------------------------------------- what a job imports


def _robot(argv: list[str], cwd: Path) -> str | None:
    """The robot of a recorded job's campaign (``None``: a command over every family's)."""
    opts = dict(zip(argv, argv[1:]))
    if "--campaign" in opts:
        return yaml.safe_load((cwd / opts["--campaign"]).read_text())["robot"]
    if "--campaigns" in opts:
        return yaml.safe_load((cwd / opts["--campaigns"]).read_text())["robot"]
    if "--history" in opts:
        return json.loads((cwd / opts["--history"]).read_text())["robot"]
    return None


def _uncovered(work: Path) -> tuple[int, dict[str, list[str]]]:
    """Jobs recorded in ``work/module-log`` (tests/module_log), and per job the calflow or
    family modules it imported that its command's digest does not cover."""
    logs = sorted((work / "module-log").glob("*.json"))
    missing = {}
    for log in logs:
        job = json.loads(log.read_text())
        argv = job["argv"]
        if argv[0] not in entry_points():
            continue
        covered = set(closure(entry_point(argv[0]), _robot(argv, Path(job["cwd"]))))
        if absent := sorted(set(job["modules"]) - covered):
            missing[" ".join(argv[:3])] = absent
    return len(logs), missing


def test_every_module_a_job_imports_is_in_its_digest(reduced_run):
    jobs, missing = _uncovered(reduced_run)
    assert jobs >= 10, "the reduced run's jobs recorded their modules"
    assert missing == {}


def test_every_module_a_default_run_job_imports_is_in_its_digest(thesis_run):
    jobs, missing = _uncovered(thesis_run)
    assert jobs >= 50
    assert missing == {}


# ---------------------------------------------------------------------------- edits


_DIGESTS = """
import json, sys
from calflow.cli import entry_point
from calflow.provenance import closure, code_digest
pairs = json.loads(sys.argv[1])
print(json.dumps({f"{c} {r}": [code_digest(c, r), closure(entry_point(c), r)] for c, r in pairs}))
"""


@pytest.fixture(scope="module")
def source_copy(tmp_path_factory) -> Path:
    """A copy of calflow's source, which the edits below change (first on PYTHONPATH)."""
    src = tmp_path_factory.mktemp("source") / "src"
    shutil.copytree(ROOT / "src" / "calflow", src / "calflow", ignore=shutil.ignore_patterns("__pycache__"))
    return src


def _digests(src: Path, cache: Path) -> dict[str, tuple[str, list[str]]]:
    env = {**os.environ, "PYTHONPATH": str(src), "CALFLOW_CACHE_DIR": str(cache)}
    proc = subprocess.run(
        [sys.executable, "-c", _DIGESTS, json.dumps(_commands())],
        env=env,
        capture_output=True,
        text=True,
        cwd=src.parent,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout)


def _edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert old in text, f"{path}: {old!r}"
    path.write_text(text.replace(old, new, 1))


@pytest.mark.process  # five processes import every step of an edited copy of calflow
def test_a_code_change_reruns_exactly_the_steps_that_reach_it(source_copy, tmp_path):
    cache = tmp_path / "cache"
    before = _digests(source_copy, cache)
    assert before == _digests(source_copy, tmp_path / "cold"), "the cache gives what the source gives"

    # comments and docstrings, in a module every step reaches and in a deep one: no digest moves
    reference, uncertainty = (
        source_copy / "calflow" / "configuration" / "reference.py",
        source_copy / "calflow" / "instruments" / "interferometer.py",
    )
    _edit(reference, '"""', '# a comment\n"""Edited docstring.\n\n')
    _edit(
        reference, "def declared(campaign: dict) -> dict:\n", "def declared(campaign: dict) -> dict:  # why\n"
    )
    _edit(uncertainty, '"""', '"""An edited docstring; ')
    assert _digests(source_copy, cache) == before

    # a real change deep in the summaries of the nano campaigns: exactly those steps move
    deep = "calflow.instruments.interferometer"
    uncertainty.write_text(uncertainty.read_text() + "\n\n_EDITED = 1\n")
    after = _digests(source_copy, cache)
    moved = {k for k in before if after[k][0] != before[k][0]}
    reach = {k for k, (_, modules) in before.items() if deep in modules}
    assert moved == reach
    assert reach and len(reach) < len(before) / 4, reach  # deep: few steps reach it
    for key in reach:  # not imported by the command's own module: found through others
        entry_module = entry_point(key.split()[0]).partition(":")[0]
        text = (ROOT / "src" / Path(*entry_module.split("."))).with_suffix(".py")
        assert not text.exists() or "calflow.instruments.interferometer" not in text.read_text()

    # and in calflow/configuration/reference.py, which every campaign's validation reaches
    reference.write_text(reference.read_text() + "\n\n_EDITED = 2\n")
    last = _digests(source_copy, cache)
    assert {k for k in after if last[k][0] != after[k][0]} == {
        k for k, (_, modules) in after.items() if "calflow.configuration.reference" in modules
    }
    assert "summarise xytheta" in {k for k in after if last[k][0] != after[k][0]}  # once left out


def test_a_docstring_edit_reruns_nothing(reduced_run, tmp_path):
    """Snakemake, given the edited source, finds the reduced run complete; a code change in
    calflow/configuration/reference.py reruns the campaign's summary (which reaches it through the
    campaign's validation)."""
    src = tmp_path / "src"
    shutil.copytree(ROOT / "src" / "calflow", src / "calflow", ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("configuration/reference.py", "configuration/config.py", "xytheta/report/summary.py"):
        path = src / "calflow" / name
        text = path.read_text()
        first = text.index('"""') + 3
        path.write_text("# an added comment\n" + text[:first] + "Edited. " + text[first:])
    env = {
        "PYTHONPATH": os.pathsep.join([str(src), str(ROOT / "tests")]),
        "CALFLOW_CACHE_DIR": str(tmp_path / "c"),
    }
    proc = snakemake(reduced_run, "-n", env_extra=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "Nothing to be done" in proc.stdout + proc.stderr

    path = src / "calflow" / "configuration" / "reference.py"
    path.write_text(path.read_text() + "\n\n_EDITED = 1\n")
    proc = snakemake(reduced_run, "-n", "--quiet", "rules", env_extra=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    jobs = dict(re.findall(r"^(\w+)\s+(\d+)\s*$", proc.stdout + proc.stderr, re.M))
    assert jobs.get("summarise") == "1", jobs
