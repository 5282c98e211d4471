"""Reliability: every emulator fault during a campaign, and SIGKILLs of acquisitions.

The fault table of docs/reliability.md: each fault is injected mid-run into a nano
training through the E-727-class emulator; the run either survives (every sample once, in
order) or fails with one message that says how to resume, with every acquired sample kept
in the journal. The SIGKILL chain is the small version of benchmarks/reliability_sigkill.py.
"""

from __future__ import annotations

import importlib.util
import math
import threading

import numpy as np
import pytest
from conftest import ROOT, SMALL_NANO1D

from calflow.acquisition.checkpoint import Journal, plan_digest
from calflow.acquisition.runner import acquire
from calflow.data.runs import RunMetadata
from calflow.errors import RigError
from calflow.gcs.rig import gcs
from calflow.nano.plans import sequences as plans
from calflow.nano.stage.emulate import emulated_rig_options

META = RunMetadata(campaign="faults", robot="stage1d", source="gcs", plan="training", config_sha256="0" * 64)
PLAN = plans.training_1d(np.arange(0.0, 481.0, 80.0), 2, 4.0, 2.0, 0.0)  # 28 samples


class Dropout:
    """Wraps the sensor: readings ``nan_at`` are NaN (no valid reading), ``fail_at`` raises."""

    def __init__(self, sensor, nan_at=(), fail_at=None):
        self.inner, self.nan_at, self.fail_at, self.n = sensor, set(nan_at), fail_at, 0
        self.sensors, self.thermometers = sensor.sensors, sensor.thermometers

    def moved(self, positions, time_s):
        self.inner.moved(positions, time_s)

    def read(self, positions, time_s):
        return self._out(self.inner.read(positions, time_s), lambda v: math.nan)

    def stream(self, times, positions):
        return self._out(self.inner.stream(times, positions), lambda v: np.full_like(v, np.nan))

    def _out(self, values, blank):
        self.n += 1
        if self.n - 1 == self.fail_at:
            raise RigError("interferometer: laser signal lost (beam blocked)")
        if self.n - 1 in self.nan_at:
            return {k: (blank(v) if k in self.sensors else v) for k, v in values.items()}
        return values

    def close(self):
        self.inner.close()


def _run(tmp_path, inject, *, options=None, sensor=None):
    """Acquire PLAN with ``inject(emu, rig)`` called after 10 samples; (ds | error, journal)."""
    emu, opts = emulated_rig_options(SMALL_NANO1D, time_scale=1000.0, timeout=0.2)
    journal = Journal(tmp_path / "run.nc.journal", plan_digest(PLAN))
    try:
        rig = gcs(**{**opts, "reconnect": {"tries": 4, "backoff_s": 0.01}, **(options or {})})
        if sensor:
            rig.sensor = sensor(rig.sensor)

        def progress(done, total):
            if done == 10:
                inject(emu, rig)

        try:
            return acquire(PLAN, rig, META, journal, progress), journal
        except RigError as exc:
            return exc, journal
        finally:
            rig.close()
    finally:
        emu.stop()


def _intact(ds):
    assert ds.sizes["sample"] == len(PLAN)
    assert np.array_equal(ds["cmd_x"].values, PLAN.commands["x"])
    assert np.array_equal(ds["pose"].values, PLAN.pose)
    assert np.all(np.diff(ds["time"].values) > 0)


def _slow_for(emu, seconds, delay):
    emu.faults.delay = delay
    threading.Timer(seconds, lambda: setattr(emu.faults, "delay", 0.0)).start()


SURVIVED = {
    "dropped connection": lambda emu, rig: setattr(emu.faults, "drop_after", 2),
    "all connections dropped": lambda emu, rig: emu.drop_connections(),
    "delay past the timeout": lambda emu, rig: _slow_for(emu, 0.3, 0.5),
    "garbled reply": lambda emu, rig: setattr(emu.faults, "garbage", 1),
    "refused reconnection": lambda emu, rig: (setattr(emu.faults, "refuse", 2), emu.drop_connections()),
}


@pytest.mark.parametrize("fault", sorted(SURVIVED))
def test_link_faults_mid_campaign_are_survived(tmp_path, fault):
    ds, _ = _run(tmp_path, SURVIVED[fault])
    assert not isinstance(ds, Exception), ds
    _intact(ds)
    assert np.isfinite(ds["meas_x"].values).all()


def test_sensor_dropout_is_recorded_as_missing_and_the_run_survives(tmp_path):
    ds, _ = _run(tmp_path, lambda emu, rig: None, sensor=lambda s: Dropout(s, nan_at=(12, 13)))
    _intact(ds)
    bad = ~np.isfinite(ds["meas_x"].values)
    assert list(np.flatnonzero(bad)) == [12, 13]


FAILED = {
    "garbled replies that persist": (
        lambda emu, rig: setattr(emu.faults, "garbage", 10**6),
        None,
        "garbage in reply",
    ),
    "controller error code": (lambda emu, rig: setattr(emu.faults, "error", 1), None, "GCS error 5"),
    "controller gone": (
        lambda emu, rig: (setattr(emu.faults, "refuse", 10**6), emu.drop_connections()),
        None,
        "reconnecting failed",
    ),
    "sensor failure": (lambda emu, rig: None, lambda s: Dropout(s, fail_at=12), "laser signal lost"),
}


@pytest.mark.parametrize("fault", sorted(FAILED))
def test_fatal_faults_fail_with_a_resume_message_and_keep_every_sample(tmp_path, fault):
    inject, sensor, cause = FAILED[fault]
    err, journal = _run(tmp_path, inject, sensor=sensor)
    assert isinstance(err, RigError), err
    message = str(err)
    assert cause in message and "\n" not in message
    assert "run the same command again to continue" in message
    kept = journal.load()
    assert len(kept) >= 10  # every sample acquired before the fault
    assert [r["cmd_x"] for r in kept] == list(PLAN.commands["x"][: len(kept)])


def _sigkill_module():
    spec = importlib.util.spec_from_file_location(
        "reliability_sigkill", ROOT / "benchmarks" / "reliability_sigkill.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.process  # SIGKILLs three acquisition processes
def test_a_chain_of_sigkills_resumes_to_the_uninterrupted_dataset(tmp_path):
    """Small version of the benchmark: 3 kills of one acquisition on the (slowed) simulated
    rig, each resumed (a kill through the GCS emulator: tests/gcs/test_rigs_gcs.py)."""
    bench = _sigkill_module()
    result = bench.kill_chain(
        "simulated", tmp_path, kills=3, rng=np.random.default_rng(5), poses=300, max_delay_s=0.1
    )
    assert result["kills"] == 3
    assert result["lost"] == 0 and result["duplicated"] == 0
    assert result["journal_never_shrank"] and result["equal_to_uninterrupted"]


# --------------------------------------------------------------------------- fuzzing the readers
# Property: whatever the bytes, a reader gives a result or one calflow error line — never a
# traceback — and a refused input leaves no output and no partial file.
from conftest import SMALL_XYTHETA  # noqa: E402
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st

from calflow.cli import main  # noqa: E402

FUZZ = settings(
    max_examples=25,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
VALUES = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**6), 10**6),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=12),
    st.lists(st.floats(allow_nan=True), max_size=4),
    st.dictionaries(st.text(max_size=6), st.integers(), max_size=2),
)


def _paths(node, prefix=()):
    if isinstance(node, dict):
        for k, v in node.items():
            yield prefix + (k,)
            yield from _paths(v, prefix + (k,))


CAMPAIGN_PATHS = sorted(_paths(SMALL_XYTHETA), key=str)


def _cli(argv, capsys):
    status = main([str(a) for a in argv])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    return status, err


@FUZZ
@given(edits=st.lists(st.tuples(st.sampled_from(CAMPAIGN_PATHS), VALUES), min_size=1, max_size=3))
def test_fuzzed_campaign_files_load_or_give_one_line(tmp_path_factory, edits):
    import copy

    import yaml

    from calflow.configuration.campaign import load as load_campaign
    from calflow.errors import CalflowError

    c = copy.deepcopy(SMALL_XYTHETA)
    for path, value in edits:
        node = c
        for key in path[:-1]:
            node = node[key] if isinstance(node.get(key), dict) else node.setdefault(key, {})
            if not isinstance(node, dict):
                break
        else:
            node[path[-1]] = value
    f = tmp_path_factory.mktemp("yaml") / "fuzz.yaml"
    f.write_text(yaml.safe_dump(c))
    try:
        load_campaign(f, [])
    except CalflowError as exc:
        assert "\n" not in str(exc) and str(exc).startswith(f"{f}: "), str(exc)


@FUZZ
@given(text=st.text(alphabet=st.sampled_from(list("0123456789.,;-e \nabcnaN:\t\"'#")), max_size=200))
def test_fuzzed_yaml_text_loads_or_gives_one_line(tmp_path_factory, text):
    import yaml

    from calflow.configuration.campaign import load as load_campaign
    from calflow.errors import CalflowError

    f = tmp_path_factory.mktemp("yaml") / "fuzz.yaml"
    f.write_text(yaml.safe_dump(SMALL_XYTHETA) + text)
    try:
        load_campaign(f, [])
    except CalflowError as exc:
        assert "\n" not in str(exc) and str(f) in str(exc), str(exc)


CSV_HEADER = "t_s,X,Y,T,xv,yv,tv"
CELLS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.text(alphabet=st.sampled_from(list('0123456789.-eE naN,;"')), max_size=6),
)


@FUZZ
@given(
    rows=st.lists(st.lists(CELLS, min_size=5, max_size=8), max_size=5),
    header=st.sampled_from([CSV_HEADER, CSV_HEADER.replace("yv", "yy"), "", CSV_HEADER + ",t_s"]),
)
def test_fuzzed_csv_imports_or_gives_one_line_and_no_file(tmp_path_factory, capsys, rows, header):
    import yaml
    from bad_input.test_bad_input import CSV_MAPPING

    d = tmp_path_factory.mktemp("csv")
    (d / "bench.csv").write_text("\n".join([header, *(",".join(r) for r in rows)]) + "\n")
    (d / "mapping.yaml").write_text(yaml.safe_dump(CSV_MAPPING))
    (d / "c.yaml").write_text(yaml.safe_dump(SMALL_XYTHETA))
    out = d / "runs" / "run.nc"
    status, err = _cli(
        [
            "import-csv",
            d / "bench.csv",
            "--mapping",
            d / "mapping.yaml",
            "--campaign",
            d / "c.yaml",
            "--out",
            out,
        ],
        capsys,
    )
    if status == 0:
        assert out.exists()
    else:
        assert status == 2 and len(err) == 1 and "bench.csv" in err[0], err
        assert not out.exists()
    leftovers = [p.name for p in (d / "runs").iterdir()] if (d / "runs").exists() else []
    assert not [n for n in leftovers if "partial" in n or n.startswith(".")], leftovers


@pytest.fixture(scope="module")
def good_run(tmp_path_factory):
    from calflow.data.io import write_dataset
    from calflow.xytheta.plans import poses as xy_plans
    from calflow.xytheta.stage.rig import simulated_xytheta

    meta = RunMetadata(
        campaign="t", robot="xytheta", source="simulated", plan="identification", config_sha256="0" * 64
    )
    ds = acquire(xy_plans.identification(6, seed=3), simulated_xytheta(seed=1, stream="id"), meta)
    return write_dataset(ds, tmp_path_factory.mktemp("nc") / "identification.nc").read_bytes()


@FUZZ
@given(data=st.data())
def test_fuzzed_netcdf_validates_or_gives_one_line(tmp_path_factory, capsys, good_run, data):
    raw = bytearray(good_run)
    cut = data.draw(st.integers(0, len(raw)), label="truncate at")
    flips = data.draw(
        st.lists(st.tuples(st.integers(0, len(raw) - 1), st.integers(0, 255)), max_size=8), label="byte flips"
    )
    for i, b in flips:
        raw[i] = b
    f = tmp_path_factory.mktemp("nc") / "identification.nc"
    f.write_bytes(bytes(raw[:cut]) if data.draw(st.booleans(), label="truncate") else bytes(raw))
    status, err = _cli(["validate", f], capsys)
    assert status in (0, 1, 2)
    assert status == 0 or (err and all(str(f) in line or line.startswith("calflow") for line in err)), err


# --------------------------------------------------------------------------- user text, names
EVIL_TEXT = (
    "<img src=x onerror=alert(1)> </td></table><script>x()</script> "
    r"$\input{/etc/passwd}$ \def\x{1} {{ 7*7 }} & \\"
)


def test_user_text_with_html_or_latex_reaches_the_index_escaped():
    """HTML in a description is escaped; LaTeX and template syntax stay inert text (the
    reports load no math renderer, and Jinja does not evaluate values)."""
    from markupsafe import escape

    from calflow.report import render_index

    summary = {
        "campaign": "c1",
        "robot": "stage1d",
        "description": EVIL_TEXT,
        "rig": "gcs",
        "seed": 1,
        "reference": {},
        "tests": {},
    }
    html = render_index([summary])
    assert "<script>x()" not in html and "<img src=x" not in html and "</td></table><script>" not in html
    assert str(escape(EVIL_TEXT)) in html
    assert r"$\input{/etc/passwd}$" in html and "{{ 7*7 }}" in html and ">49<" not in html
    assert "mathjax" not in html.lower() and "katex" not in html.lower()


@pytest.mark.parametrize(
    "name", ["..", "../evil", "a/b", "/abs", "x\n", ".hidden", "", "a" * 65, "c:evil", "evil name"]
)
def test_campaign_names_cannot_leave_results_or_reports(tmp_path, name):
    """A name names folders under results/ and reports/: only letters, digits, '-', '_'."""
    from calflow.configuration.config import check_campaign_name, load_workflow_config
    from calflow.errors import ConfigError

    with pytest.raises(ConfigError, match="expected letters, digits"):
        check_campaign_name(name)  # the workflow's gate (workflow/rules/common.smk)
    if name != "x\n":  # JSON Schema's pattern is searched: "$" matches before a final newline
        with pytest.raises(ConfigError):
            load_workflow_config({"campaigns": [name]})


def test_a_campaign_file_whose_stem_is_not_a_name_is_refused_by_the_workflow(tmp_path):
    """``...yaml`` has the stem ``..``: the workflow's name check refuses it."""
    from calflow.configuration.config import check_campaign_name
    from calflow.errors import ConfigError

    assert (tmp_path / "...yaml").stem == ".."
    with pytest.raises(ConfigError):
        check_campaign_name((tmp_path / "...yaml").stem)
    assert check_campaign_name("nano1d-thesis") == "nano1d-thesis"


@pytest.mark.parametrize("key", ["\n", "a\nb", "x\ry", "\x85", "\u2028", "tab\there"])
def test_a_key_with_a_line_break_is_named_in_one_line(tmp_path, key):
    """The fuzzer's find: a key holding a line break was quoted raw, so the message broke
    into two lines; it is shown escaped."""
    import copy

    import yaml

    from calflow.configuration.campaign import load as load_campaign
    from calflow.errors import CalflowError

    c = copy.deepcopy(SMALL_XYTHETA)
    c["rig"][key] = 1
    f = tmp_path / "c.yaml"
    f.write_text(yaml.safe_dump(c))
    with pytest.raises(CalflowError) as info:
        load_campaign(f, [])
    message = str(info.value)
    assert "\n" not in message and "\r" not in message and message.startswith(f"{f}: ")
    assert "rig." + key.encode("unicode_escape").decode() in message
