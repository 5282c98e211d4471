"""The family contract (calflow.family_contract): a family that does not keep it is refused
when it registers, with one line naming the family, the hook and what was expected."""

from __future__ import annotations

import dataclasses
import sys
import textwrap

import pytest

import calflow.family as registry
from calflow import hook_source
from calflow.family_contract import HOOKS, FamilyError, check_family


@pytest.fixture
def module(tmp_path, monkeypatch):
    """Write a module of hooks on the path: ``module(source)`` -> its name."""
    monkeypatch.syspath_prepend(str(tmp_path))

    def write(source: str, name: str = "lab_hooks") -> str:
        (tmp_path / f"{name}.py").write_text(textwrap.dedent(source))
        hook_source._summary.cache_clear()
        hook_source.locate.cache_clear()
        sys.modules.pop(name, None)
        return name

    yield write
    hook_source._summary.cache_clear()
    hook_source.locate.cache_clear()


def _xytheta():
    return next(f for f in registry.families() if f.name == "xytheta")


def _with_step(step: str, target: str):
    fam = _xytheta()
    return dataclasses.replace(fam, name="lab", steps={**fam.steps, step: target})


def _refused(fam) -> str:
    with pytest.raises(FamilyError) as err:
        check_family(fam)
    line = str(err.value)
    assert "\n" not in line and line.startswith("family 'lab': hook ")
    return line


def test_the_installed_families_keep_the_contract():
    names = [fam.name for fam in registry.families()]
    assert {"xytheta", "nano", "hexapod"} <= set(names)
    for fam in registry.families():
        check_family(fam)


def test_every_required_hook_missing_is_refused_by_name():
    fam = dataclasses.replace(_xytheta(), name="lab")
    for h in (h for h in HOOKS if h.required):
        if h.field == "steps":
            step = h.name.split(".", 1)[1]
            bad = dataclasses.replace(fam, steps={k: v for k, v in fam.steps.items() if k != step})
        else:
            bad = dataclasses.replace(fam, **{h.field: {} if h.shape == "by_robot" else None})
        line = _refused(bad)
        assert f"hook {h.name}:" in line and "missing" in line and h.call in line


def test_a_step_that_takes_other_parameters_is_refused(module):
    name = module(
        """
        def old(args): ...
        def renamed(campaign, args): ...
        def more(c, args, out): ...
        def kw_only(c, args, *, out): ...
        def fine(c, args, verbose=False, **extra): ...
        """
    )
    line = _refused(_with_step("identify", f"{name}:old"))
    assert "steps.identify" in line and "identify(c, args)" in line and "takes 1 positional" in line
    line = _refused(_with_step("identify", f"{name}:renamed"))
    assert "parameters named ['campaign', 'args']" in line
    assert "takes 3 positional" in _refused(_with_step("metrics", f"{name}:more"))
    assert "keyword-only" in _refused(_with_step("summarise", f"{name}:kw_only"))
    check_family(_with_step("identify", f"{name}:fine"))  # defaults and **extra are fine


def test_a_hook_that_names_nothing_is_refused(module):
    name = module("def identify(c, args): ...\n")
    assert "no module 'lab_nowhere'" in _refused(_with_step("identify", "lab_nowhere:identify"))
    assert "no module 'calflow.nowhere'" in _refused(_with_step("identify", "calflow.nowhere:f"))
    line = _refused(_with_step("identify", f"{name}:identfy"))
    assert f"module {name!r} has no attribute 'identfy'" in line
    assert "expected a 'module:attribute' string" in _refused(
        _with_step("identify", "calflow.configuration.layout")
    )


def test_a_value_where_a_function_is_expected_is_refused(module):
    name = module(
        """
        IDENTIFY = {"free": ["x_R"]}
        from calflow.family_contract import TEMPLATE as METRICS
        """
    )
    assert "not callable" in _refused(_with_step("identify", f"{name}:IDENTIFY"))
    assert "not callable" in _refused(_with_step("metrics", f"{name}:METRICS"))  # followed to its module
    fam = dataclasses.replace(
        _xytheta(), name="lab", reference={"lab-set": "calflow.configuration.layout:run"}
    )
    assert "got a function" in _refused(fam)


def test_steps_and_their_options_are_declared_objects():
    """A family's own steps are calflow.step.Step, what it adds to a core step Options of a step
    that takes them; a Step's function is checked like any hook."""
    from calflow.step import Option

    fam = dataclasses.replace(_xytheta(), name="lab", step_options={"acquire": ("--luts",)})
    assert "step_options.acquire: expected calflow.step.Option" in _refused(fam)
    fam = dataclasses.replace(_xytheta(), name="lab", step_options={"summarise": (Option("--x"),)})
    assert "step_options.summarise" in _refused(fam)
    fam = dataclasses.replace(_xytheta(), name="lab", commands=(("lab-step", "help", "m:f"),))
    assert "commands: expected a calflow.step.Step" in _refused(fam)
    command = dataclasses.replace(_xytheta().commands[0], run="calflow.configuration.layout:run")
    fam = dataclasses.replace(_xytheta(), name="lab", commands=(command,))
    assert f"commands.{command.name}.run" in _refused(fam)


def test_a_rig_without_its_option_check_is_refused():
    fam = _xytheta()
    factory = fam.rigs["xytheta"]["simulated"]
    bad = dataclasses.replace(fam, name="lab", options={k: v for k, v in fam.options.items() if k != factory})
    assert factory in _refused(bad)


def test_named_files_must_exist():
    fam = dataclasses.replace(_xytheta(), name="lab")
    assert "templates/xytheta.html.j2" in _refused(dataclasses.replace(fam, templates="calflow.data"))
    assert "index_row" in _refused(dataclasses.replace(fam, index_row="absent_row.html.j2"))
    assert "schemas" in _refused(dataclasses.replace(fam, schemas="calflow.data"))
    rules = (fam.rules[0], "rules/absent.smk")
    assert "rules/absent.smk" in _refused(dataclasses.replace(fam, rules=rules))


def test_a_workflow_of_the_wrong_type_is_refused_when_asked(module):
    name = module("WORKFLOW = dict(models=[])\n")
    fam = dataclasses.replace(_xytheta(), name="lab", workflow=f"{name}:WORKFLOW")
    check_family(fam)  # an object built at import: its type is known only once imported
    with pytest.raises(FamilyError, match=r"family 'lab': hook workflow: .*FamilyWorkflow, got dict"):
        fam.hooks()
    assert "FamilyWorkflow" in _refused(dataclasses.replace(fam, workflow="calflow.family_contract:TEMPLATE"))


def test_the_emulator_is_an_emulator_object_not_a_main():
    fam = dataclasses.replace(_xytheta(), name="lab")
    check_family(dataclasses.replace(fam, emulator="calflow.nano.stage.emulate:EMULATOR"))
    line = _refused(dataclasses.replace(fam, emulator="calflow.xytheta.stage.emulate:physics_options"))
    assert "hook emulator" in line and "calflow.gcs.emulation.campaign_emulator.Emulator" in line
    assert "Emulator" in _refused(dataclasses.replace(fam, emulator="calflow.family_contract:TEMPLATE"))


def test_an_emulator_of_the_wrong_type_is_refused_when_served(module):
    from calflow.family_contract import built_of

    name = module("EMULATOR = dict(main=None)\n")
    fam = dataclasses.replace(_xytheta(), name="lab", emulator=f"{name}:EMULATOR")
    check_family(fam)  # an object built at import: its type is known only once imported
    with pytest.raises(FamilyError, match=r"family 'lab': hook emulator: .*emulator.Emulator, got dict"):
        built_of(fam, "emulator")
    assert type(built_of(_xytheta(), "emulator")).__name__ == "Emulator"


def test_registration_refuses_a_family_that_breaks_the_contract(module, tmp_path, monkeypatch):
    """Through the entry point, as an installed distribution registers: families() refuses it."""
    name = module(
        """
        import dataclasses
        from calflow.xytheta.family import FAMILY as _BASE

        FAMILY = dataclasses.replace(
            _BASE, name="lab", robots=("labbot",), rigs={"labbot": _BASE.rigs["xytheta"]},
            plans={"labbot": _BASE.plans["xytheta"]}, joints={"labbot": ("x",)},
            templates="calflow.xytheta.report", schemas=None, index_row=None,
            steps={**_BASE.steps, "metrics": "lab_steps:metrics"},
        )
        """,
        "lab_family",
    )
    module("def metrics(run, out): ...\n", "lab_steps")
    dist = tmp_path / "calflow_lab-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: calflow-lab\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(f"[calflow.families]\nlab = {name}:FAMILY\n")
    registry.families.cache_clear()
    try:
        with pytest.raises(FamilyError) as err:
            registry.families()
    finally:
        monkeypatch.undo()
        registry.families.cache_clear()
    assert str(err.value).startswith(
        "family 'lab': hook steps.metrics: 'lab_steps:metrics': expected metrics(c, args)"
    )


def test_hooks_bound_in_ways_the_source_does_not_show_plainly_are_still_checked(module):
    """``a, b = f, g`` binds pairwise (read from the source); a name the source does not bind
    plainly (a loop over ``globals()``) is asked of Python: a right hook registers, a wrong
    one is refused by its signature either way."""
    name = module(
        """
        def step(c, args):
            return None

        def other(args):
            return None

        identify, metrics = step, other
        for _name in ("summarise", "figures"):
            globals()[_name] = step if _name == "summarise" else other
        """
    )
    check_family(_with_step("identify", f"{name}:identify"))
    check_family(_with_step("summarise", f"{name}:summarise"))
    for step in ("metrics", "figures"):
        line = _refused(_with_step(step, f"{name}:{step}"))
        assert f"steps.{step}" in line and "(args)" in line


def test_registering_the_families_imports_none_of_their_code():
    """The contract is read from the families' sources: registering them (what every calflow
    command and every read of the Snakefile does) imports no module of theirs, so it stays
    cheap and a step's rerun digest covers what its job imports."""
    import subprocess

    code = (
        "import sys\nfrom calflow.family import families\nfamilies()\n"
        "print(' '.join(m for m in sys.modules if m.startswith(('calflow.', 'calflow_'))))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        check=True,
        env={"CALFLOW_CACHE_DIR": ""},
    ).stdout.split()
    families_code = [
        m
        for m in out
        if m.split(".")[-1] != "family"
        and m.startswith(("calflow.xytheta.", "calflow.nano.", "calflow_hexapod."))
    ]
    assert families_code == []
