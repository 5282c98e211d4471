"""Tables of a dataset as CSV files with units in the header, and back.

A table dataset (the position table, an angle table of a model file) is split by
dimensions: every data variable over the same dimensions goes to one CSV file in long
format — one column per dimension (its coordinate, or the index when it has none), one
per variable — with headers ``name [unit]``. Scalars, attributes, shapes and dtypes are
described in JSON (:func:`describe`), so :func:`rebuild` restores the dataset exactly
(floats are written with 17 significant digits).
"""

from __future__ import annotations

import csv
import io
import re
from pathlib import Path

import numpy as np
import xarray as xr

from calflow.data.io import jsonable, write_text
from calflow.errors import DataError

_HEADER = re.compile(r"^(?P<name>[^\[\]]+?) \[(?P<unit>[^\[\]]*)\]$")


def _fmt(v) -> str:
    return str(int(v)) if isinstance(v, (int, np.integer)) else format(float(v), ".17g")


def write_tables(ds: xr.Dataset, folder, prefix: str) -> dict:
    """Write ``ds``'s array variables as CSV files ``<prefix>_<dims>.csv`` in ``folder``
    (atomically); return the JSON description :func:`rebuild` needs."""
    folder = Path(folder)
    groups: dict[tuple, list[str]] = {}
    for name, var in ds.data_vars.items():
        if var.ndim:
            groups.setdefault(var.dims, []).append(name)
    files = {}
    for dims, names in groups.items():
        shape = tuple(ds.sizes[d] for d in dims)
        columns, headers = [], []
        for k, d in enumerate(dims):
            if d in ds.coords:
                values, unit = ds[d].values, ds[d].attrs.get("units", "1")
            else:
                values, unit = np.arange(shape[k]), "index"
            columns.append(
                np.broadcast_to(
                    values.reshape([-1 if j == k else 1 for j in range(len(dims))]), shape
                ).ravel()
            )
            headers.append(f"{d} [{unit}]")
        for name in names:
            columns.append(ds[name].transpose(*dims).values.ravel())
            headers.append(f"{name} [{ds[name].attrs.get('units', '1')}]")
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(headers)
        w.writerows([_fmt(c[i]) for c in columns] for i in range(columns[0].size))
        file = f"{prefix}_{'_'.join(dims)}.csv"
        write_text(buf.getvalue(), folder / file)
        files[file] = {"dims": list(dims), "shape": list(shape), "variables": names}
    return {
        "files": files,
        "coords": {
            d: {
                "dtype": "int" if np.issubdtype(ds[d].dtype, np.integer) else "float",
                "attrs": jsonable(dict(ds[d].attrs)),
            }
            for d in ds.coords
        },
        "variables": {n: jsonable(dict(ds[n].attrs)) for n in ds.data_vars},
        "scalars": {n: jsonable(float(ds[n].values)) for n in ds.data_vars if ds[n].ndim == 0},
        "attrs": jsonable(dict(ds.attrs)),
    }


def read_csv(path) -> tuple[list[str], list[str], np.ndarray]:
    """Names, units and values (rows × columns) of a CSV file written by :func:`write_tables`."""
    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: file not found")
    rows = list(csv.reader(path.read_text().splitlines()))
    if not rows:
        raise DataError(f"{path}: empty; expected a header 'name [unit],...'")
    names, units = [], []
    for h in rows[0]:
        m = _HEADER.match(h.strip())
        if m is None:
            raise DataError(f"{path}: header {h!r}: expected 'name [unit]'")
        names.append(m["name"])
        units.append(m["unit"])
    try:
        values = np.array([[float(v) for v in r] for r in rows[1:]], dtype=float).reshape(-1, len(names))
    except ValueError:
        raise DataError(f"{path}: expected {len(names)} numbers on every line after the header") from None
    return names, units, values


def rebuild(folder, description: dict) -> xr.Dataset:
    """The dataset :func:`write_tables` described, from its CSV files in ``folder``."""
    folder = Path(folder)
    data, coords = {}, {}
    for file, spec in description["files"].items():
        names, units, values = read_csv(folder / file)
        dims, shape = tuple(spec["dims"]), tuple(spec["shape"])
        expected = [*dims, *spec["variables"]]
        if names != expected or values.shape[0] != int(np.prod(shape)):
            raise DataError(
                f"{folder / file}: expected columns {expected} and {int(np.prod(shape))} rows, "
                f"got {names} and {values.shape[0]}"
            )
        for k, d in enumerate(dims):
            if units[k] == "index" or d in coords:
                continue
            axis = values[:, k].reshape(shape)
            line = axis[tuple(slice(None) if j == k else 0 for j in range(len(dims)))]
            c = description["coords"].get(d, {})
            line = line.astype(np.int64 if c.get("dtype") == "int" else float)
            coords[d] = xr.Variable((d,), line, attrs=c.get("attrs", {}))
        for j, name in enumerate(spec["variables"]):
            data[name] = xr.Variable(
                dims, values[:, len(dims) + j].reshape(shape), attrs=description["variables"].get(name, {})
            )
    for name, value in description["scalars"].items():
        data[name] = xr.Variable(
            (), float("nan") if value is None else float(value), attrs=description["variables"].get(name, {})
        )
    return xr.Dataset(data, coords=coords, attrs=description["attrs"])
