"""Atomic reading and writing of calflow files.

Every output is written to a temporary name in the same directory and renamed when
complete, so an interrupted job never leaves a half-written file under the final name.
"""

from __future__ import annotations

import contextlib
import glob
import hashlib
import json
import math
import os
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from calflow.errors import DataError

if TYPE_CHECKING:  # imported where a dataset is opened: writing text needs no xarray
    import xarray as xr


def output_folder(path: str | os.PathLike) -> Path:
    """Create the folder of output ``path``; :class:`DataError` naming it when it cannot be."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        blocker = next(
            (p for p in [path.parent, *path.parent.parents] if p.exists() and not p.is_dir()), path.parent
        )
        raise DataError(f"{path}: cannot create its folder: {blocker} is a file, not a folder") from None
    except OSError as exc:
        raise DataError(f"{path}: cannot create its folder {path.parent} ({exc.strerror})") from None
    if os.path.exists(path) and os.path.isdir(path):
        raise DataError(f"{path}: is a folder; expected a file name to write")
    return path.parent


def remove_stale_partials(path: str | os.PathLike) -> list[Path]:
    """Remove the temporary files a killed writer of ``path`` left (``.<name>.*.partial``)."""
    path = Path(path)
    stale = sorted(path.parent.glob(f".{glob.escape(path.name)}.*.partial"))
    for p in stale:
        with contextlib.suppress(FileNotFoundError):
            p.unlink()
    return stale


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success.

    On any exception the temporary file is removed and ``path`` is left untouched.
    Temporaries a killed earlier writer left are removed first; the file gets the mode
    an ordinary ``open`` would give it (``0o666`` less the umask), not ``mkstemp``'s 0600.
    """
    path = Path(path)
    output_folder(path)
    remove_stale_partials(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".partial", dir=path.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        os.chmod(tmp_path, 0o666 & ~_umask())
        os.replace(tmp_path, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp_path.unlink()
        raise


def _encoding(ds: xr.Dataset) -> dict:
    """Compressed numeric data; CF coordinate variables (named as their dimension) carry no
    ``_FillValue`` (CF 2.5.1: they must have no missing values)."""
    enc = {
        name: {"zlib": True, "complevel": 4}
        for name, var in ds.data_vars.items()
        if var.dtype.kind in "fiu" and var.ndim > 0
    }
    enc.update(
        {name: {"_FillValue": None} for name in ds.coords if name in ds.dims and ds[name].dtype.kind == "f"}
    )
    return enc


def write_dataset(
    ds: xr.Dataset, path: str | os.PathLike, groups: dict[str, xr.Dataset] | None = None
) -> Path:
    """Write ``ds`` as netCDF4 to ``path`` atomically and return the path.

    ``groups`` are written as netCDF groups of the same file (e.g. a model's lookup tables).
    A file without a ``title`` (CF 2.6.2) gets one from its kind, campaign, plan and model.
    """
    if not ds.attrs.get("title"):
        ds = ds.copy()
        ds.attrs["title"] = title(ds.attrs)
    with atomic_path(path) as tmp:
        ds.to_netcdf(tmp, engine="netcdf4", format="NETCDF4", encoding=_encoding(ds))
        for name, group in (groups or {}).items():
            group.to_netcdf(
                tmp, mode="a", group=name, engine="netcdf4", format="NETCDF4", encoding=_encoding(group)
            )
    return Path(path)


def title(attrs: Mapping[str, Any]) -> str:
    """A one-line CF ``title``: e.g. ``calflow run identification of campaign xytheta-thesis``."""
    what = " ".join(str(attrs[k]) for k in ("calflow_kind", "plan") if attrs.get(k))
    model = f" (model {attrs['model']})" if attrs.get("model") else ""
    return f"calflow {what or 'dataset'}{model} of campaign {attrs.get('campaign', 'unnamed')}"


def group_names(path: str | os.PathLike) -> list[str]:
    """Names of the netCDF groups of a file."""
    import netCDF4

    with netCDF4.Dataset(path) as nc:
        return list(nc.groups)


def jsonable(value):
    """``value`` as plain JSON types: numpy scalars and arrays become Python numbers and
    lists, tuples become lists, non-finite floats become None, keys become strings."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if hasattr(value, "item") and callable(value.item):  # 0-d arrays and the like
        return jsonable(value.item())
    return str(value)


def write_json(obj: Any, path: str | os.PathLike) -> Path:
    """Write ``obj`` as indented, key-sorted JSON to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(obj, indent=2, sort_keys=True, allow_nan=True) + "\n")
    return Path(path)


def write_text(text: str, path: str | os.PathLike) -> Path:
    """Write ``text`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def write_bytes(data: bytes, path: str | os.PathLike) -> Path:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def open_dataset(path: str | os.PathLike, kind: str | None = None, group: str | None = None) -> xr.Dataset:
    """Open a calflow netCDF file fully into memory.

    Raises :class:`DataError` with one line naming the file and the problem when the file
    is missing, not netCDF, or of another ``calflow_kind`` than ``kind``.
    """
    import xarray as xr

    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: file not found")
    try:
        with xr.open_dataset(path, engine="netcdf4", decode_times=False, group=group) as ds:
            ds = ds.load()
    except Exception as exc:  # netCDF4 raises OSError/RuntimeError/ValueError variously
        raise DataError(f"{path}: not a readable netCDF4 file ({type(exc).__name__}: {exc})") from None
    if kind is not None and group is None and ds.attrs.get("calflow_kind") != kind:
        raise DataError(
            f"{path}: attribute 'calflow_kind': expected {kind!r}, got {ds.attrs.get('calflow_kind')!r}"
        )
    return ds


def sha256_file(path: str | Path) -> str:
    """SHA-256 of the file's bytes, as hex (the provenance of summaries, reports, bundles)."""
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def load_summary(path: str | Path) -> dict:
    return json.loads(Path(path).read_text())
