"""The environmental conditions of a campaign's runs, as a certificate states them.

ISO/IEC 17025:2017 §7.8.4.1 a) asks a calibration certificate for the conditions under which
the calibration was made that influence the results. For a positioning stage that is the
temperature: every run dataset may carry ``temperature`` (sample, sensor) in °C from the
rig's thermometers (docs/data.md). The certificate states, over the campaign's runs, the
lowest, highest and mean reading and the largest excursion within one run, with the
thermometers and runs they come from. A campaign whose runs record no temperature says so.
"""

from __future__ import annotations

import math
from pathlib import Path


def run_files(files: list[str]) -> list[str]:
    """The run datasets among a campaign's result files (``…/runs/<id>.nc``)."""
    return sorted(f for f in files if f.endswith(".nc") and Path(f).parent.name == "runs")


def temperatures(path: str):
    """The finite temperature readings (°C) of one run, flattened, and its thermometers' names;
    ``(None, ())`` without a ``temperature`` variable."""
    import numpy as np
    import xarray as xr

    from calflow.summary_routing import already_open

    ds = already_open(path)  # the summary job's own dataset, else only the temperature is read
    with xr.open_dataset(path, engine="netcdf4", decode_times=False) if ds is None else ds as ds:
        if "temperature" not in ds:
            return None, ()
        t = np.asarray(ds["temperature"].values, float)
        names = tuple(str(s) for s in ds["sensor"].values) if "sensor" in ds.coords else ()
    return t[np.isfinite(t)], names


def environment(files: list[str]) -> dict:
    """``{temperature_degC: {min, max, mean, max_excursion}, thermometers, runs, statement}``
    over the campaign's runs (module notes); without any reading, only the statement."""
    import numpy as np

    values, sensors, runs, excursion = [], [], [], 0.0
    for f in run_files(files):
        t, names = temperatures(f)
        if t is None or t.size == 0:
            continue
        values.append(t)
        runs.append(Path(f).stem)
        sensors += [n for n in names if n not in sensors]
        excursion = max(excursion, float(t.max() - t.min()))
    if not values:
        return {
            "temperature_degC": None,
            "thermometers": [],
            "runs": [],
            "statement": "the runs record no temperature: the environmental conditions are not known to calflow",
        }
    t = np.concatenate(values)
    out = {"min": float(t.min()), "max": float(t.max()), "mean": float(t.mean()), "max_excursion": excursion}
    out = {k: round(v, 4) if math.isfinite(v) else None for k, v in out.items()}
    return {
        "temperature_degC": out,
        "thermometers": sensors,
        "runs": runs,
        "statement": (
            f"temperature {out['min']:.2f} °C to {out['max']:.2f} °C (mean {out['mean']:.2f} °C, largest "
            f"excursion within a run {out['max_excursion']:.2f} °C), read by {len(sensors) or 'the'} "
            f"thermometer(s) of the rig during {len(runs)} run(s)"
        ),
    }
