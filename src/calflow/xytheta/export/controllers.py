"""Per-axis double-sided compensation tables for motion controllers (LinuxCNC, TwinCAT CNC).

A controller's axis (joint) compensation is one-dimensional: at nominal commanded
positions N of one joint it holds one correction for travel in the positive direction and
one for the negative direction, interpolates linearly in N and adds the correction of the
current direction of travel to the command. Of calflow's XY tables (Eq. 4.14, 4.15,
:class:`calflow.xytheta.tables.position.PositionLUT`) a per-axis table expresses the own-axis
terms f_xx/b_xx (X) and f_yy/b_yy (Y) only; the cross-axis terms (f_yx/b_yx: x error
while Y moves, f_xy/b_xy: y error while X moves), the kinematic parameters and the angle
table stay with the kinematics (the controller-neutral bundle, :mod:`.bundle`).

The model commands X = N + e(X) (the stage reaches X − e, Eq. 4.18); a controller reads
its table at the *nominal* command N. The table therefore holds the fixed point
t(N) = e(N + t(N)) of the own-axis table per direction, so nominal + t reproduces the
model's command exactly at the table's entries.

LinuxCNC (``[JOINT_n] COMP_FILE``, ``COMP_FILE_TYPE = 1``; docs/src/config/ini-config.adoc
and src/emc/motion/control.c ``compute_screw_comp``): one line per entry,
``nominal forward_trim reverse_trim`` in machine units, ascending nominal, at most 256
lines; the motion controller adds the forward trim while the joint's commanded velocity
is positive and the reverse trim while it is negative, both signed, interpolated
linearly at the nominal position command. The reader stops at the first line that is
not three numbers, so the file carries no comments.

TwinCAT CNC double-sided leadscrew error compensation (SSFK, ``kw.ssfk.*``, P-COMP-00017
to -00025): ``kw.ssfk.table[i].setpoint`` (programmed position), ``.pos`` and ``.neg``
(compensation values for positive and negative travel) in 0.1 µm integers
(``kw.ssfk.unit 1``), ``kw.ssfk.bilateral 1``; the values are position errors
Δs = actual − programmed, which the CNC subtracts from the setpoint, so calflow writes
Δs = −t.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.interpolate import make_lsq_spline

from calflow.data.io import write_text
from calflow.errors import DataError
from calflow.xytheta.tables.position import _interpolator, infer_directions

LINUXCNC_MAX_ENTRIES = 256  # "the limit inside LinuxCNC is for 256 triplets per joint"
TWINCAT_MAX_ENTRIES = 1500  # kw.ssfk.max_points default (P-COMP-00059)
MM_PER_UM = 1e-3


@dataclass(frozen=True)
class AxisCompensation:
    """Corrections (µm) added to a joint's command at nominal positions ``nominal`` (µm,
    strictly ascending): ``forward`` while the joint moves in +, ``reverse`` in −."""

    axis: str
    nominal: np.ndarray
    forward: np.ndarray
    reverse: np.ndarray

    def __post_init__(self) -> None:
        n = np.asarray(self.nominal, dtype=float)
        if n.ndim != 1 or n.size < 2 or not np.all(np.diff(n) > 0):
            raise ValueError(f"axis {self.axis}: nominal positions must be >= 2 and strictly ascending")
        for name in ("forward", "reverse"):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != n.shape or not np.all(np.isfinite(v)):
                raise ValueError(f"axis {self.axis}: {name} must be {n.size} finite values")

    def correction(self, nominal, direction) -> np.ndarray:
        """The correction (µm) at nominal commands (µm) travelled in ``direction`` (±1):
        linear between entries, the end value outside (the controller's first/last entry)."""
        nominal = np.asarray(nominal, dtype=float)
        d = np.broadcast_to(np.asarray(direction), nominal.shape)
        return np.where(
            d > 0,
            np.interp(nominal, self.nominal, self.forward),
            np.interp(nominal, self.nominal, self.reverse),
        )

    def command(self, nominal, start: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Joint commands (µm) a controller sends for a sequence of nominal commands: nominal
        plus the correction of the direction of travel (sign of the change of the nominal
        command from ``start``; no change keeps the last direction). Returns commands, directions."""
        nominal = np.asarray(nominal, dtype=float).ravel()
        d = infer_directions(nominal, start)
        return nominal + self.correction(nominal, d), d


def from_position_table(
    lut, axis: str, method: str = "linear", max_entries: int | None = None, iterations: int = 6
) -> tuple[AxisCompensation, dict]:
    """The own-axis part of a :class:`PositionLUT` as a per-axis compensation.

    At each of the table's own positions N the correction is the fixed point t = e(N + t)
    (``iterations`` steps, as the model's inverse) of the forward (b: backward) table,
    interpolated with ``method``. When there are more than ``max_entries`` positions, the
    entries are ``max_entries`` equally spaced over the range, with the values of the
    least-squares piecewise-linear fit to t (what the controller interpolates) rather than
    samples of it, which would keep the table's point noise. Returns the compensation and
    ``resampling_error_um``: per direction, the largest difference at the table's own
    positions between the file's linear interpolation and the full table's fixed point.
    """
    if axis not in ("x", "y"):
        raise ValueError(f"axis: expected 'x' or 'y', got {axis!r}")
    pos = np.asarray(lut.x_position if axis == "x" else lut.y_position, dtype=float)
    table = np.asarray(lut.xx if axis == "x" else lut.yy, dtype=float)
    ok = np.all(np.isfinite(table), axis=1) & np.isfinite(pos)
    grid = full = pos[ok]
    if max_entries is not None and grid.size > max_entries:
        grid = np.linspace(grid[0], grid[-1], int(max_entries))
    trims, errors = [], {}
    for col, label in ((0, "forward"), (1, "reverse")):
        f = _interpolator(pos, table[:, col], method, f"{axis} table ({label})", "clamp")

        def fixed_point(q, f=f):
            t = f(q)
            for _ in range(iterations - 1):
                t = f(q + t)
            return t

        t_full = fixed_point(full)
        t = (
            t_full
            if grid is full
            else make_lsq_spline(full, t_full, np.r_[grid[0], grid, grid[-1]], k=1)(grid)
        )
        trims.append(t)
        errors[label] = float(np.max(np.abs(np.interp(full, grid, t) - t_full)))
    return AxisCompensation(axis, grid, trims[0], trims[1]), {"resampling_error_um": errors}


# --- LinuxCNC -------------------------------------------------------------------------


def write_linuxcnc(comp: AxisCompensation, path) -> Path:
    """``COMP_FILE_TYPE = 1`` file in millimetres (machine units ``mm``), atomically."""
    if comp.nominal.size > LINUXCNC_MAX_ENTRIES:
        raise ValueError(
            f"axis {comp.axis}: {comp.nominal.size} entries, LinuxCNC reads at most {LINUXCNC_MAX_ENTRIES}"
        )
    lines = [
        f"{n * MM_PER_UM:.7f} {f * MM_PER_UM:.7f} {r * MM_PER_UM:.7f}"
        for n, f, r in zip(comp.nominal, comp.forward, comp.reverse)
    ]
    return write_text("\n".join(lines) + "\n", path)


def read_linuxcnc(path, axis: str) -> AxisCompensation:
    """A ``COMP_FILE_TYPE = 1`` file (mm) back as µm; every line must be three numbers (LinuxCNC
    would silently stop reading at the first that is not)."""
    rows = []
    lines = Path(path).read_text().rstrip().splitlines()
    for k, line in enumerate(lines, start=1):  # LinuxCNC stops at a blank line too: refused here
        try:
            values = [float(v) for v in line.split()]
        except ValueError:
            values = []
        if len(values) != 3 or not all(np.isfinite(values)):
            raise DataError(
                f"{path}: line {k}: expected 'nominal forward_trim reverse_trim' (three numbers, mm), "
                f"got {line.strip()!r}"
            )
        rows.append(values)
    if len(rows) > LINUXCNC_MAX_ENTRIES:
        raise DataError(
            f"{path}: {len(rows)} lines, expected at most {LINUXCNC_MAX_ENTRIES} (LinuxCNC's limit)"
        )
    a = np.asarray(rows, dtype=float).reshape(-1, 3) / MM_PER_UM
    try:
        return AxisCompensation(axis, a[:, 0], a[:, 1], a[:, 2])
    except ValueError as exc:
        raise DataError(f"{path}: {exc}") from None


# --- TwinCAT CNC ----------------------------------------------------------------------

_KEY = re.compile(r"^(kopf\.[a-z_]+|kw\.ssfk\.[a-z_]+|kw\.ssfk\.table\[(\d+)\]\.(setpoint|pos|neg))\s+(\S+)")


def write_twincat(comp: AxisCompensation, path, axis_number: int, provenance: str = "") -> Path:
    """A double-sided, non-equidistant SSFK compensation value list (0.1 µm), atomically.

    Setpoints and values are rounded to 0.1 µm, the list's resolution."""
    if comp.nominal.size > TWINCAT_MAX_ENTRIES:
        raise ValueError(
            f"axis {comp.axis}: {comp.nominal.size} entries, more than kw.ssfk.max_points' "
            f"default {TWINCAT_MAX_ENTRIES}"
        )
    tenth = lambda v: np.rint(np.asarray(v, dtype=float) * 10.0).astype(np.int64)  # noqa: E731
    setpoint, pos, neg = tenth(comp.nominal), tenth(-comp.forward), tenth(-comp.reverse)
    if not np.all(np.diff(setpoint) > 0):
        raise ValueError(f"axis {comp.axis}: entries closer than 0.1 um")
    out = [f"# {line}" for line in provenance.splitlines()]
    out += [
        f"kopf.achs_nr                 {int(axis_number)}",
        f"kopf.log_achs_name           {comp.axis.upper()}",
        "kw.ssfk.unit                 1",
        "kw.ssfk.interval             0",
        f"kw.ssfk.kw_startpos          {setpoint[0]}",
        f"kw.ssfk.kw_nr_max            {setpoint.size}",
        "kw.ssfk.bilateral            1",
        "kw.ssfk.modulo               0",
    ]
    for field, values in (("setpoint", setpoint), ("pos", pos), ("neg", neg)):
        out += [f"kw.ssfk.table[{i}].{field:<10} {int(v)}" for i, v in enumerate(values)]
    return write_text("\n".join(out) + "\n", path)


def read_twincat(path, axis: str | None = None) -> tuple[AxisCompensation, int]:
    """An SSFK list written in 0.1 µm back as corrections in µm (t = −Δs); returns it and
    the logical axis number ``kopf.achs_nr``."""
    keys, table = {}, {}
    for k, line in enumerate(Path(path).read_text().splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        m = _KEY.match(s)
        if m is None:
            raise DataError(f"{path}: line {k}: expected 'kopf.*' or 'kw.ssfk.*' KEY VALUE, got {s!r}")
        try:
            value = int(m.group(4)) if m.group(2) is not None else m.group(4)
        except ValueError:
            raise DataError(
                f"{path}: line {k}: {m.group(1)}: expected an integer (0.1 um), got {m.group(4)!r}"
            ) from None
        if m.group(2) is not None:
            table.setdefault(int(m.group(2)), {})[m.group(3)] = value
        else:
            keys[m.group(1)] = value
    if keys.get("kw.ssfk.unit") != "1" or keys.get("kw.ssfk.bilateral") != "1":
        raise DataError(
            f"{path}: kw.ssfk.unit and kw.ssfk.bilateral: expected 1 (metric 0.1 um, double-sided)"
        )
    n = int(keys.get("kw.ssfk.kw_nr_max", -1))
    if sorted(table) != list(range(n)) or any(len(table[i]) != 3 for i in table):
        raise DataError(
            f"{path}: kw.ssfk.table: expected setpoint, pos and neg for entries 0..{n - 1} "
            f"(kw.ssfk.kw_nr_max {n})"
        )
    a = (
        np.array([[table[i]["setpoint"], table[i]["pos"], table[i]["neg"]] for i in range(n)], dtype=float)
        / 10.0
    )
    name = axis or str(keys.get("kopf.log_achs_name", "?")).lower()
    try:
        return AxisCompensation(name, a[:, 0], -a[:, 1], -a[:, 2]), int(keys.get("kopf.achs_nr", 0))
    except ValueError as exc:
        raise DataError(f"{path}: {exc}") from None
