"""An ISO 230-2 run's U kept between summaries (calflow.commands.kept): the same records as
computing it, read back without computing, and computed again when anything it depends on changes."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow import cache
from calflow.commands import kept
from calflow.metrics import uncertainty_iso
from calflow.metrics.uncertainty import Term

TRIALS = 2000  # fixed M: small and fast; the adaptive default is the same code path


def sweeps(seed: int, targets: int = 5, cycles: int = 3):
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 100.0, targets)
    f = t[:, None] + 0.3 + rng.normal(0, 0.1, (targets, cycles))
    b = t[:, None] + rng.normal(0, 0.1, (targets, cycles))
    return t, f, b


def records(found: dict) -> str:
    """Every field a summary writes, as its bytes."""
    return json.dumps({name: u.record() | {"value": u.value} for name, u in found.items()}, sort_keys=True)


@pytest.fixture
def folder(tmp_path, monkeypatch):
    monkeypatch.setenv("CALFLOW_CACHE_DIR", str(tmp_path / "cache"))
    cache.cache_dir.cache_clear()
    yield tmp_path / "cache" / "iso230_2"
    cache.cache_dir.cache_clear()


def counting(monkeypatch) -> list:
    """Count the computations under :mod:`calflow.commands.kept`."""
    calls = []
    real = uncertainty_iso.iso230_2_uncertainty

    def compute(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(uncertainty_iso, "iso230_2_uncertainty", compute)
    return calls


@settings(max_examples=8, deadline=None)
@given(
    seed=st.integers(0, 2**16),
    targets=st.integers(2, 7),
    cycles=st.integers(2, 4),
    term=st.floats(0.0, 0.2),
    origin=st.floats(-50.0, 50.0),
)
def test_kept_records_are_the_computed_ones_to_the_byte(
    tmp_path_factory, seed, targets, cycles, term, origin
):
    t, f, b = sweeps(seed, targets, cycles)
    terms = [Term("drift", term, scope="target"), Term("scale", 2.0, relative=True)]
    direct = records(uncertainty_iso.iso230_2_uncertainty(t, f, b, terms, origin=origin, trials=TRIALS))
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("CALFLOW_CACHE_DIR", str(tmp_path_factory.mktemp("cache")))
        cache.cache_dir.cache_clear()
        try:
            first = records(kept.iso230_2_uncertainty(t, f, b, terms, origin=origin, trials=TRIALS))
            again = records(kept.iso230_2_uncertainty(t, f, b, terms, origin=origin, trials=TRIALS))
        finally:
            cache.cache_dir.cache_clear()
    assert first == direct
    assert again == direct


def test_a_kept_result_is_read_back_without_computing(folder, monkeypatch):
    t, f, b = sweeps(1)
    calls = counting(monkeypatch)
    first = kept.iso230_2_uncertainty(t, f, b, trials=TRIALS)
    second = kept.iso230_2_uncertainty(t, f, b, trials=TRIALS)
    assert len(calls) == 1
    assert len(list(folder.glob("*.json"))) == 1
    assert records(first) == records(second)
    assert all(u.samples is None for u in second.values())


def test_without_a_cache_it_computes_each_time(monkeypatch):
    monkeypatch.setenv("CALFLOW_CACHE_DIR", "")
    cache.cache_dir.cache_clear()
    try:
        t, f, b = sweeps(2)
        calls = counting(monkeypatch)
        kept.iso230_2_uncertainty(t, f, b, trials=TRIALS)
        kept.iso230_2_uncertainty(t, f, b, trials=TRIALS)
        assert len(calls) == 2
    finally:
        cache.cache_dir.cache_clear()


@pytest.mark.parametrize(
    "change",
    ["reading", "target", "shape", "term", "origin", "trials", "seed", "code"],
)
def test_any_change_it_depends_on_computes_it_again(folder, monkeypatch, change):
    t, f, b = sweeps(3)
    args = {"terms": (Term("drift", 0.05, scope="target"),), "origin": 0.0, "trials": TRIALS, "seed": 0}
    calls = counting(monkeypatch)
    before = kept.iso230_2_uncertainty(t, f, b, **args)
    f2, t2, b2 = f.copy(), t.copy(), b
    if change == "reading":  # one reading by one unit in the last place
        f2[2, 1] = np.nextafter(f2[2, 1], np.inf)
    elif change == "target":
        t2[0] = np.nextafter(t2[0], -np.inf)
    elif change == "shape":  # the same numbers, another table
        t2, f2, b2 = t[:4], f[:4], b[:4]
    elif change == "term":
        args["terms"] = (Term("drift", 0.05, scope="common"),)
    elif change == "origin":
        args["origin"] = 1e-9
    elif change == "trials":
        args["trials"] = TRIALS + 1000
    elif change == "seed":
        args["seed"] = 1
    elif change == "code":  # another source of a module the computation reaches
        from calflow import provenance

        real = provenance.module_digest
        monkeypatch.setattr(provenance, "module_digest", lambda *m: "x" + real(*m))
    after = kept.iso230_2_uncertainty(t2, f2, b2, **args)
    assert len(calls) == 2
    assert len(list(folder.glob("*.json"))) == 2
    direct = uncertainty_iso.iso230_2_uncertainty(t2, f2, b2, **args)
    assert records(after) == records(direct)
    if change in ("trials", "seed", "term"):
        assert records(after) != records(before)


def test_every_field_a_summary_writes_is_kept():
    from dataclasses import fields

    from calflow.metrics.uncertainty import Uncertainty

    assert set(kept.FIELDS) == {f.name for f in fields(Uncertainty)} - {"samples"}


def test_numpy_numbers_infinite_dof_and_notes_come_back_the_same(folder, monkeypatch):
    from calflow.metrics.uncertainty import Uncertainty

    made = Uncertainty(
        np.float64(0.1) + np.float64(0.2),
        np.float64(1 / 3),
        1.96,
        np.float64(2 / 3) / 1.96,
        float("inf"),
        (np.float64(-1e-300), np.float64(5e-324)),
        {"sample": np.float64(0.7), "drift": 0.0},
        "Monte Carlo, M = 10 000",
        "the standard's value lies outside the interval",
        samples=np.arange(3.0),
        monte_carlo={"trials": np.int64(10_000), "tolerance": np.float64(0.05), "blocks": [1, 2]},
    )
    monkeypatch.setattr(uncertainty_iso, "iso230_2_uncertainty", lambda *a, **k: {"E": made})
    t, f, b = sweeps(4)
    for _ in range(2):  # computed, then read back
        back = kept.iso230_2_uncertainty(t, f, b)["E"]
        plain = {"default": lambda o: o.item()}  # the summary's writer: numpy scalars as numbers
        assert json.dumps(back.record(), **plain) == json.dumps(made.record(), **plain)
        assert back.value == made.value and back.samples is None


def test_the_code_digest_covers_the_monte_carlo_it_keeps():
    from calflow.provenance import closure

    reached = set(closure(kept.COMPUTES))
    assert {
        "calflow.metrics.uncertainty_iso",
        "calflow.metrics.uncertainty.stream",
        "calflow.metrics.uncertainty.draws",
        "calflow.metrics.uncertainty.montecarlo",
        "calflow.metrics.uncertainty.budget",
        "calflow.metrics.iso230_2",
    } <= reached
