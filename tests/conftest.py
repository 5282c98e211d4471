"""Shared fixtures: small campaigns in a scratch copy of the workflow."""

from __future__ import annotations

import inspect
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]

# ---------------------------------------------------------------------------- hypothesis
import hypothesis_profiles  # noqa: E402, F401  (registers and loads the profiles: tests/hypothesis_profiles.py)

# ---------------------------------------------------------------------------- tiers
# `make test-fast` runs what is not marked `workflow`: the unit and property tests. A test
# is a workflow test when it uses a whole-run fixture or runs Snakemake itself.
WORKFLOW_FIXTURES = {"thesis_run", "reduced_run", "shipped_recordings_run"}
WORKFLOW_CALLS = ("snakemake(", "make_workdir(", "run_cluster", "bench_workflow")


def pytest_configure(config):
    # Under --dist loadfile, pytest-xdist sends files in the order collected (not sorted by
    # their number of tests, its default), so the files that read the default run come last
    # (pytest_collection_modifyitems below) and no worker idles waiting for that run early.
    if hasattr(config.option, "loadscopereorder"):
        config.option.loadscopereorder = False


_SOURCES: dict = {}


def _runs_workflow(func, module, seen: set) -> bool:
    """Whether ``func``'s source, or a function or fixture of its module it names (to any
    depth), runs the workflow."""
    import inspect

    if func in seen:
        return False
    seen.add(func)
    if func not in _SOURCES:  # each function read once (collection reads thousands of items)
        try:
            _SOURCES[func] = inspect.getsource(func)
        except (OSError, TypeError):
            _SOURCES[func] = None
    source = _SOURCES[func]
    if source is None:
        return False
    if any(call in source for call in WORKFLOW_CALLS) or any(f in source for f in WORKFLOW_FIXTURES):
        return True
    for name, value in vars(module).items():
        target = getattr(value, "__wrapped__", value)
        if (
            inspect.isfunction(target)
            and target.__module__ == module.__name__
            and f"{name}(" in source
            and _runs_workflow(target, module, seen)
        ):
            return True
    return False


def pytest_collection_modifyitems(config, items):
    import sys as _sys

    verdicts: dict = {}  # the parametrised items of one test share theirs
    for item in items:
        fixtures = set(getattr(item, "fixturenames", ()))
        func = getattr(item, "function", None)
        module = _sys.modules.get(getattr(func, "__module__", ""), None)
        found = bool(WORKFLOW_FIXTURES & fixtures)
        key = (func, frozenset(fixtures))
        if not found and key in verdicts:
            found = verdicts[key]
        elif not found and func is not None and module is not None:
            seen: set = set()
            found = _runs_workflow(func, module, seen)
            for name in fixtures:  # the module's or conftest's fixtures the test uses
                for fixturedef in item._fixtureinfo.name2fixturedefs.get(name, ()):
                    fmod = _sys.modules.get(getattr(fixturedef.func, "__module__", ""), None)
                    if not found and fmod is not None:
                        found = _runs_workflow(fixturedef.func, fmod, seen)
            verdicts[key] = found
        if found:
            item.add_marker(pytest.mark.workflow)
    # The files that read the default run go last, so that under xdist every worker runs the
    # rest while that run (started when collection ends, below) is under way, instead of one
    # worker waiting for it. Whole files move (--dist loadfile schedules by file).
    # Among them the longest go first (LATE_FIRST), so the last file handed to a worker is a
    # short one and neither worker idles long while the other ends the suite.
    # (a list in collection order, not a set: the order must be the same in every xdist worker)
    late = list(dict.fromkeys(item.path for item in items if _reads_thesis_run(item)))
    rank = {name: k for k, name in enumerate(LATE_FIRST)}
    order = sorted(late, key=lambda path: rank.get(path.name, len(rank)))  # stable: the rest as collected
    position = {path: k for k, path in enumerate(order)}
    items[:] = [i for i in items if i.path not in late] + sorted(
        (i for i in items if i.path in late), key=lambda i: position[i.path]
    )


#: Files that read the default run, longest first (their wall times in a suite run, seconds:
#: about 35, 35, 22, 18, 15 on the 2-core machine); any other such file follows them.
LATE_FIRST = (
    "test_reports_browser.py",
    "test_default_year.py",
    "test_default_certificates.py",
    "test_default_outputs.py",
    "test_provenance.py",
)


def _reads_thesis_run(item) -> bool:
    """Whether ``item`` uses the default run: as a fixture (to any depth), or asks for it by
    name (``request.getfixturevalue("thesis_run")``) in its module."""
    if "thesis_run" in getattr(item, "fixturenames", ()):
        return True
    module = getattr(item, "module", None)
    if module not in _SOURCES:
        try:
            _SOURCES[module] = inspect.getsource(module)
        except (OSError, TypeError):
            _SOURCES[module] = None
    return 'getfixturevalue("thesis_run")' in (_SOURCES[module] or "")


def pytest_collection_finish(session):
    """Start the default run in the background as soon as a selected test will read it."""
    if session.config.option.collectonly:
        return
    # A module that asks for the run by name may also hold tests that do not (the browser
    # checks' own test): only a selected workflow test starts it, so `make test-fast` never does.
    if any(item.get_closest_marker("workflow") and _reads_thesis_run(item) for item in session.items):
        start_thesis_run(_shared_folder(session.config))


def _xy_noise_um() -> float:
    from calflow.xytheta.stage.rig import XYThetaTruth

    t = XYThetaTruth()
    return float((t.sensor_noise_um**2 + t.stage_repeatability_um**2) ** 0.5)


XY_NOISE_UM = _xy_noise_um()  # one reading's noise on the default simulated XYΘ rig (sensor, stage), µm
BIN = Path(sys.executable).parent

SMALL_XYTHETA = {
    "description": "small test campaign",
    "robot": "xytheta",
    "seed": 7,
    "rig": {"factory": "simulated", "options": {}},
    "characterisation": {"x_stop_um": 4400, "y_stop_um": 3200, "step_um": 25, "cycles": 2, "dwell_s": 0.2},
    "xy_tests": {
        "compensation": ["none", "linear"],
        "square": {"side_um": 1000, "points_per_segment": 4, "cycles": 2},
        "random_points": {"cycles": 2, "targets": [[500, 300], [1500, 900], [2500, 1200]]},
    },
    "identification": {"poses": 60, "dwell_s": 0.5},
    "observability": {"max_poses": 200, "steps": 5, "repeats": 1},
    "angle_residuals": {"cycles": 2, "positions": 2, "step_deg": 0.25},
    "models": {
        "I": {"free": ["x_R", "y_R"], "fixed": {"alpha": 180.0, "beta": 0.0}},
        "II": {"free": ["x_R", "y_R", "alpha", "beta"]},
        "III": {"free": ["x_R", "y_R", "alpha", "beta"], "position_table": True},
        "IV": {"base": "II", "angle_table": True},
    },
    "validation": {
        "cycles": 4,
        "dwell_s": 0.5,
        "heldout": {"targets": 12, "cycles": 3, "error_budget": False},
    },
}

SMALL_NANO1D = {
    "robot": "stage1d",
    "seed": 3,
    "rig": {
        "factory": "simulated",
        "options": {"profile": "lab5day"},
        "runs": {"metrology": {"profile": "metrology"}},
    },
    "training": {"step_um": 60, "cycles": 6, "dwell_s": 10.0},
    "metrology": {"cycles": 3, "step_um": 160, "dwell_s": 8.0},
    "validation": {"step_um": 160, "cycles": 3, "tests": 6, "dwell_s": 8.0, "start_h": 2.0},
}

SMALL_NANO2D = {
    "robot": "stage2d",
    "seed": 4,
    "rig": {"factory": "simulated", "options": {"profile": "lab5day"}},
    "training": {"step_um": 20, "cycles": 3, "dwell_s": 6.0},
    "validation": {"cycles": 3, "tests": 4, "dwell_s": 6.0, "start_h": 1.0},
}


def make_workdir(tmp: Path, campaigns: dict[str, dict], rig_plugins: list[str] | None = None) -> Path:
    """A scratch project: the repository's Snakefile and workflow with the given campaigns.

    ``rig_plugins``: the config's allow-list of rig plug-in modules (e.g. ``["toyrigs"]``).
    """
    work = tmp / "project"
    work.mkdir()
    shutil.copy(ROOT / "Snakefile", work / "Snakefile")
    shutil.copytree(ROOT / "workflow", work / "workflow")
    (work / "config" / "campaigns").mkdir(parents=True)
    cfg = {"campaigns": list(campaigns), **({"rig_plugins": list(rig_plugins)} if rig_plugins else {})}
    (work / "config" / "config.yaml").write_text(yaml.safe_dump(cfg))
    for name, body in campaigns.items():
        text = body if isinstance(body, str) else yaml.safe_dump(body)
        (work / "config" / "campaigns" / f"{name}.yaml").write_text(text)
    return work


def _snakemake_env(env_extra: dict | None) -> dict:
    env = {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}"}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT / "tests"), env.get("PYTHONPATH")]))
    env.update(env_extra or {})
    return env


def snakemake(work: Path, *args: str, env_extra: dict | None = None) -> subprocess.CompletedProcess:
    """Run Snakemake of this environment in ``work``."""
    return subprocess.run(
        [str(BIN / "snakemake"), "--cores", "2", *args],
        cwd=work,
        env=_snakemake_env(env_extra),
        capture_output=True,
        text=True,
        timeout=1800,  # a hang guard, not a speed check: the default run is ~6 min on a quiet machine
    )


def module_log(work: Path) -> dict:
    """Environment under which each ``calflow`` job of a run in ``work`` records the calflow
    and family modules it imported, in ``work/module-log`` (tests/module_log, read by
    tests/project/test_provenance.py)."""
    (work / "module-log").mkdir(exist_ok=True)
    paths = [str(ROOT / "tests" / "module_log"), str(ROOT / "tests"), os.environ.get("PYTHONPATH")]
    return {
        "CALFLOW_MODULE_LOG": str(work / "module-log"),
        "PYTHONPATH": os.pathsep.join(filter(None, paths)),
    }


@pytest.fixture
def small_campaign() -> dict:
    return yaml.safe_load(yaml.safe_dump(SMALL_XYTHETA))


def cf_problems(files) -> list[str]:
    """Failed CF-1.11 checks of weight 2 (warning) or 3 (error) of the IOOS compliance-checker.

    Run in a process of its own: after the checker has opened some fifty files, netCDF4 was
    seen to crash the process that opens the next one (a segmentation fault in
    ``netCDF4.Dataset``), which would take the rest of a test worker with it.
    """
    import json

    script = (
        "import json, sys\n"
        "from compliance_checker.runner import CheckSuite\n"
        "suite = CheckSuite(); suite.load_all_available_checkers(); problems = []\n"
        "for path in sys.argv[1:]:\n"
        "    results = suite.run_all(suite.load_dataset(path), ['cf:1.11'], skip_checks=[])['cf:1.11'][0]\n"
        "    for r in results:\n"
        "        scored, possible = r.value if isinstance(r.value, tuple) else (int(bool(r.value)), 1)\n"
        "        if r.weight >= 2 and scored < possible:\n"
        "            problems.append(f'{path}: {r.name}: {r.msgs}')\n"
        "print(json.dumps(problems))\n"
    )
    proc = subprocess.run([sys.executable, "-c", script, *map(str, files)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


# ---------------------------------------------------------------------------- shared runs
# Whole-workflow runs are the slow part of the suite: each is made once per session and
# read by every test that only reads it. The default run (thesis_run) starts in the
# background when collection ends and the files that read it are scheduled last, so the
# workers run the rest of the suite beside it rather than one waiting ~6 min for it. The
# reduced run is made once too, by whichever worker asks first (a file lock), and read by the
# other. (xdist's `loadgroup` would be the natural tool, but pytest 9 ignores the node ids it
# rewrites.)

#: SMALL_XYTHETA with Models I and II only, no XY tests and 120 poses: a run of 10 jobs.
REDUCED_XYTHETA = {
    **SMALL_XYTHETA,
    "models": {k: SMALL_XYTHETA["models"][k] for k in ("I", "II")},
    "xy_tests": {"compensation": []},
    "identification": {**SMALL_XYTHETA["identification"], "poses": 120},
}
SOURCE_DATE_EPOCH = {"SOURCE_DATE_EPOCH": "1767225600"}  # reproducible `created` attributes


THESIS_HANG_GUARD_S = 1800  # a hang guard, not a speed check: the default run is ~6 min on a quiet machine


def _shared_folder(config) -> Path:
    """The session's folder shared by its pytest-xdist workers (the controller's basetemp)."""
    base = config._tmp_path_factory.getbasetemp()
    return base.parent if hasattr(config, "workerinput") else base


def start_thesis_run(shared: Path) -> None:
    """Start the default configuration's run (the default campaigns, no study) in the
    background, once per session whichever worker asks first (a file lock in the folder the
    workers share, the pattern of pytest-xdist's docs); ``thesis/rc`` appears when it ends.

    It runs under SOURCE_DATE_EPOCH (a campaign run again gives the same bytes) and
    ``--resources mem_mb=3000`` (scheduled by the rules' declared memory, as a 4 GB lab PC
    would; each job's measured peak is held against its declaration by
    tests/workflow/test_default_outputs.py)."""
    from filelock import FileLock

    folder = shared / "thesis"
    with FileLock(shared / "thesis.lock"):
        if (folder / "started").exists():
            return
        shutil.rmtree(folder, ignore_errors=True)
        work = folder / "project"
        work.mkdir(parents=True)
        shutil.copy(ROOT / "Snakefile", work / "Snakefile")
        shutil.copytree(ROOT / "workflow", work / "workflow")
        shutil.copytree(ROOT / "config", work / "config")
        args = ["--cores", "2", "--resources", "mem_mb=3000", "--config", "studies=[]"]
        # the exit status is written under a temporary name, then renamed: rc is whole when seen
        script = '"$0" "$@" >../stdout 2>../stderr; echo $? >../rc.tmp && mv ../rc.tmp ../rc'
        proc = subprocess.Popen(
            ["sh", "-c", script, str(BIN / "snakemake"), *args],
            cwd=work,
            env=_snakemake_env({**SOURCE_DATE_EPOCH, **module_log(work)}),
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        (folder / "pid").write_text(str(proc.pid))
        (folder / "started").touch()


@pytest.fixture(scope="session")
def thesis_run(request) -> Path:
    """The default configuration run once per test session (:func:`start_thesis_run`, begun
    when collection ends): its project folder, with results/ and reports/, once the run has
    ended. Under pytest-xdist every worker shares the one run."""
    import signal
    import time

    shared = _shared_folder(request.config)
    start_thesis_run(shared)  # already started, unless collection-finish was skipped
    folder = shared / "thesis"
    deadline = time.monotonic() + THESIS_HANG_GUARD_S
    while not (folder / "rc").exists():
        if time.monotonic() > deadline:
            os.kill(int((folder / "pid").read_text()), signal.SIGTERM)
            pytest.fail(f"the default run did not end within {THESIS_HANG_GUARD_S} s")
        time.sleep(1.0)
    assert (folder / "rc").read_text().strip() == "0", (folder / "stderr").read_text()[-3000:]
    return folder / "project"


@pytest.fixture(scope="session")
def reduced_run(request) -> Path:
    """REDUCED_XYTHETA (campaign ``c``) run once per session locally under SOURCE_DATE_EPOCH,
    shared by the pytest-xdist workers (a file lock in the folder they share: the worker that
    asks first makes it, another waits for it), so the files that read it (test_reduced_run.py,
    test_provenance.py) may land on either worker. Its readers leave it as it is: a test that
    runs another campaign does so in a project of its own."""
    from filelock import FileLock

    shared = _shared_folder(request.config)
    folder = shared / "reduced"
    with FileLock(shared / "reduced.lock"):
        if (folder / "rc").exists():
            assert (folder / "rc").read_text().strip() == "0", (
                "the reduced run failed (an earlier test's report)"
            )
            return folder / "project"
        shutil.rmtree(folder, ignore_errors=True)
        folder.mkdir()
        work = make_workdir(folder, {"c": yaml.safe_load(yaml.safe_dump(REDUCED_XYTHETA))})
        proc = snakemake(work, env_extra={**SOURCE_DATE_EPOCH, **module_log(work)})
        (folder / "rc").write_text(str(proc.returncode))
        assert proc.returncode == 0, proc.stderr[-3000:]
        return work


#: The shipped recorded campaigns (config/campaigns/recorded-*.yaml) a session runs.
RECORDED = ("recorded-iso230", "recorded-tracker")


@pytest.fixture(scope="session")
def shipped_recordings_run(request) -> Path:
    """A project holding the shipped recorded campaigns (and recorded-csv's file, planned but
    not run), made once per session and shared by the pytest-xdist workers (a file lock):
    ``recorded-iso230`` run alone, then ``recorded-tracker`` alone, as a lab runs one campaign
    after another (the second run's index must list the first's campaign). Its readers leave
    it as it is (a test that deletes results does so in a copy)."""
    from filelock import FileLock

    shared = _shared_folder(request.config)
    folder = shared / "recorded"
    with FileLock(shared / "recorded.lock"):
        if (folder / "rc").exists():
            assert (folder / "rc").read_text().strip() == "0", "the recorded campaigns' runs failed"
            return folder / "project"
        shutil.rmtree(folder, ignore_errors=True)
        folder.mkdir()
        names = (*RECORDED, "recorded-csv")
        work = make_workdir(
            folder, {n: (ROOT / "config" / "campaigns" / f"{n}.yaml").read_text() for n in names}
        )
        shutil.copytree(ROOT / "tests" / "data" / "recordings", work / "tests" / "data" / "recordings")
        for name in RECORDED:
            proc = snakemake(work, "--config", f'campaigns=["{name}"]')
            if proc.returncode:
                break
        (folder / "rc").write_text(str(proc.returncode))
        assert proc.returncode == 0, proc.stderr[-3000:]
        return work
