"""Frames of HP-code markers → every marker's number and pose, and one marker's pose relative
to another's.

:func:`decode_markers` finds the markers of each frame (:mod:`.fiducials`) and gives each its
pose (:mod:`.pose`): one row per marker found, or one row for a frame with none, each with a
status of :data:`~calflow.instruments.pattern.STATUSES` and one reason; NaN, never a pose,
when the marker cannot be trusted. :func:`relative` turns two markers' poses into the pose of
one against the other over a sequence; :func:`decode` is the layout's hook — per frame, the
pose of one marker, alone or relative to a reference marker.

Conventions (docs/instruments.md, "HP-code markers"): a marker's (x, y) are the coordinates,
in µm in the marker's own frame (origin on its centre dot), of the frame centre — the pixel
((w − 1)/2, (h − 1)/2) — and Θ (degree) the direction of its x axis in the frame, as for a
Megarena target. Relative to a reference marker the reference plays the camera's part: (x, y)
are the reference's centre in the marker's frame and Θ the marker's x axis's direction in the
reference's frame, so that a stage carrying the marker gives the same signs either way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calflow.instruments.pattern.decode import Decoded
from calflow.instruments.pattern.hpcode.fiducials import find_fiducials, group
from calflow.instruments.pattern.hpcode.pattern import HPCodePattern
from calflow.instruments.pattern.hpcode.pose import marker_pose
from calflow.instruments.pattern.megarena.decode import _bad_frame, _frames

FIELDS = ("x_um", "y_um", "theta_deg", "u_x_um", "u_y_um", "u_theta_deg", "pixel_um", "u_pixel_um")
EXTRA = ("theta_x_deg", "pixel_x_um", "theta_y_deg", "pixel_y_um", "centre_x_px", "centre_y_px")
EXTRA += (
    "u_centre_x_um",
    "u_centre_y_um",
    "theta_fiducials_deg",
    "centre_fiducials_x_px",
    "centre_fiducials_y_px",
)


@dataclass(frozen=True)
class Markers:
    """One row per marker found (or per frame where none is): its frame's index, its number
    (−1 when not read), its pose and uncertainties (NaN unless ``status`` is "ok")."""

    frame: np.ndarray
    number: np.ndarray
    columns: dict  # FIELDS + EXTRA → arrays, one value per row
    status: np.ndarray
    reason: np.ndarray
    n_frames: int
    shape: tuple[int, int]

    def __len__(self) -> int:
        return len(self.status)

    def __getattr__(self, name):
        columns = self.__dict__.get("columns", {})
        if name in columns:
            return columns[name]
        raise AttributeError(name)

    def rows(self, number: int | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per frame, the row of the marker numbered ``number`` (−1 where there is none) and
        the frame's status and reason for it; ``None``: no marker, each frame's own."""
        row = np.full(self.n_frames, -1)
        status = np.full(self.n_frames, "code_mismatch", dtype=object)
        reason = np.full(self.n_frames, f"no marker numbered {number} in the frame", dtype=object)
        for f in range(self.n_frames):
            mine = np.nonzero((self.frame == f) & (self.number == number))[0]
            here = np.nonzero(self.frame == f)[0]
            if len(mine) > 1:
                status[f], reason[f] = "ambiguous", f"{len(mine)} markers numbered {number} in the frame"
            elif len(mine) == 1:
                row[f] = mine[0]
                status[f], reason[f] = self.status[mine[0]], self.reason[mine[0]]
            elif len(here) and (number is None or not (self.status[here] == "ok").any()):
                status[f], reason[f] = self.status[here[0]], self.reason[here[0]]
        return row, status.astype(str), reason.astype(str)

    def of(self, number: int | None) -> Decoded:
        """The marker numbered ``number``, one entry per frame: its pose where it was decoded,
        NaN and a reason where it was not found (or was found twice); ``None``: no marker, each
        frame's own status and reason."""
        row, status, reason = self.rows(number)
        out = {
            k: np.where(row >= 0, self.columns[k][np.maximum(row, 0)] if len(self) else np.nan, np.nan)
            for k in FIELDS[:6]
        }
        return Decoded(**out, status=status, reason=reason)

    def library_pose(self) -> dict[str, np.ndarray]:
        """Every row's pose as the Vernier library prints a marker's (``x, y, alpha, pixelSize``):
        the translation of the marker's centre dot in the camera frame at the pixel (w/2, h/2),
        in the marker's axes, where calflow gives the marker coordinates of ((w − 1)/2, (h − 1)/2)
        (docs/instruments.md)::

            x_lib = −(x + s_x·(cos α_x + sin α_x)/2),   y_lib = −(y + s_y·(cos α_y + sin α_y)/2)

        α_x, α_y the directions of the marker's axes in the frame, s_x, s_y the pixel sizes
        along them; alpha = α_x (radian), pixelSize = s_x."""
        c = self.columns
        ax, ay = np.radians(c["theta_x_deg"]), np.radians(c["theta_y_deg"])
        return {
            "x": -(c["x_um"] + 0.5 * c["pixel_x_um"] * (np.cos(ax) + np.sin(ax))),
            "y": -(c["y_um"] + 0.5 * c["pixel_y_um"] * (np.cos(ay) + np.sin(ay))),
            "alpha": ax,
            "pixelSize": c["pixel_x_um"],
        }


def _check_pixel(pixel_um) -> None:
    if pixel_um is not None and not (
        isinstance(pixel_um, (int, float)) and pixel_um > 0 and math.isfinite(pixel_um)
    ):
        raise ValueError(f"pixel_um: expected a positive number (µm), got {pixel_um!r}")


def decode_markers(frames, pattern: HPCodePattern, pixel_um: float | None = None) -> Markers:
    """Every HP-code marker of ``pattern`` in one frame (h, w) or a stack (n, h, w).

    ``pixel_um`` (µm per pixel), when given, must agree with the period the fiducials show
    (5 %); each marker's pixel size is measured from its grid either way (a relative pose
    takes the given one as its scale, :func:`relative`)."""
    _check_pixel(pixel_um)
    stack = _frames(frames)
    n, h, w = stack.shape
    rows: list[tuple[int, dict]] = []
    for f in range(n):
        problem = _bad_frame(stack[f])
        if problem:
            rows.append((f, {"status": "bad_frame", "reason": problem}))
            continue
        frame = stack[f].astype(np.float32)
        fiducials = find_fiducials(frame)
        triples = group(fiducials, pattern.size)
        if not triples:
            rows.append(
                (
                    f,
                    {
                        "status": "code_mismatch",
                        "reason": f"no HP-code marker of {pattern.size} dots a side in the frame "
                        f"({len(fiducials)} fiducial(s) found, three make one)",
                    },
                )
            )
            continue
        for triple in triples:
            rows.append((f, marker_pose(frame, triple, pattern, pixel_um)))
    columns = {k: np.array([r.get(k, np.nan) for _, r in rows], float) for k in FIELDS + EXTRA}
    return Markers(
        frame=np.array([f for f, _ in rows], int),
        number=np.array([r.get("number", -1) for _, r in rows], int),
        columns=columns,
        status=np.array([r["status"] for _, r in rows], dtype=str),
        reason=np.array([r["reason"] for _, r in rows], dtype=str),
        n_frames=n,
        shape=(h, w),
    )


def relative(
    found: Markers,
    marker: int,
    reference: int,
    period_um: float,
    pixel_um: float | None = None,
    u_pixel_um: float = 0.0,
) -> Decoded:
    """Per frame, the pose of the marker numbered ``marker`` relative to the one numbered
    ``reference`` (module docstring): the reference's centre in the marker's frame and the
    marker's x axis's direction in the reference's frame.

    The offset between the two centre dots is measured in pixels (each from its own grid's
    phase) and turned into µm in the reference's axes by the mean of the two markers' lattices
    (both see the same optics): with K_r, K_m their frequency matrices (cycles per pixel, rows
    along each marker's axes) and Θ = Θ_m − Θ_r,

        o = p · ½ (K_r + R(Θ) K_m) (c_m − c_r),   (x, y) = −R(−Θ) o

    with standard uncertainties from the two centres' and the scale's (noise only). A frame
    where either marker is not "ok" gets its status and reason, never a pose.

    ``pixel_um`` (µm per pixel), when given, is the scale: the lattice keeps each frame's
    directions and shape, its size set to it, K ← K · (pixel_um / p) / √|det K|. The markers'
    separation multiplies the scale (a relative error of 10⁻⁴ is 0.07 µm at 700 µm), and a
    frame's own estimate of it scatters more than its fit says (docs/instruments.md), so a
    pixel size known for the optics — or pooled over a sequence (:mod:`.scale`) — steadies the
    offset. Its standard uncertainty ``u_pixel_um`` (0: not known, left out) is common to the
    frames and goes into ``u_x_um``, ``u_y_um`` as |o| · u_pixel_um / pixel_um."""
    _check_pixel(pixel_um)
    rm, sm, why_m = found.rows(marker)
    rr, sr, why_r = found.rows(reference)
    n = found.n_frames
    out = {k: np.full(n, np.nan) for k in FIELDS[:6]}
    status = np.where(sm != "ok", sm, sr).astype(object)
    reason = np.where(sm != "ok", why_m, np.char.add("the reference marker: ", why_r)).astype(object)
    col = found.columns
    for f in np.nonzero((sm == "ok") & (sr == "ok"))[0]:
        i, j = rm[f], rr[f]

        def lattice(k):
            tx, ty = math.radians(col["theta_x_deg"][k]), math.radians(col["theta_y_deg"][k])
            sx, sy = col["pixel_x_um"][k] / period_um, col["pixel_y_um"][k] / period_um
            return np.array([[sx * math.cos(tx), sx * math.sin(tx)], [sy * math.cos(ty), sy * math.sin(ty)]])

        turn = math.radians(col["theta_deg"][i] - col["theta_deg"][j])
        c, s = math.cos(turn), math.sin(turn)
        rot = np.array([[c, -s], [s, c]])
        K = 0.5 * (lattice(j) + rot @ lattice(i))
        if pixel_um is not None:
            K *= pixel_um / period_um / math.sqrt(abs(np.linalg.det(K)))
        pix = np.array(
            [col["centre_x_px"][i] - col["centre_x_px"][j], col["centre_y_px"][i] - col["centre_y_px"][j]]
        )
        o = period_um * (K @ pix)
        xy = -(rot.T @ o)
        dist = math.hypot(*o)
        u_scale = (
            dist * u_pixel_um / pixel_um
            if pixel_um is not None
            else dist
            * 0.5
            * math.hypot(col["u_pixel_um"][i] / col["pixel_um"][i], col["u_pixel_um"][j] / col["pixel_um"][j])
        )
        u_turn = math.radians(math.hypot(col["u_theta_deg"][i], col["u_theta_deg"][j]))
        for axis, k in ((0, "u_centre_x_um"), (1, "u_centre_y_um")):
            out[FIELDS[3 + axis]][f] = math.sqrt(
                col[k][i] ** 2 + col[k][j] ** 2 + u_scale**2 + (dist * u_turn) ** 2
            )
        out["x_um"][f], out["y_um"][f] = xy
        out["theta_deg"][f] = (math.degrees(turn) + 180.0) % 360.0 - 180.0
        out["u_theta_deg"][f] = math.degrees(u_turn)
        status[f], reason[f] = "ok", "decoded"
    return Decoded(**out, status=status.astype(str), reason=reason.astype(str))


def decode(
    frames,
    pattern: HPCodePattern,
    pixel_um: float | None = None,
    workers: int | None = None,
    details: bool = False,
    marker: int | None = None,
    reference: int | None = None,
) -> Decoded:
    """The layout's hook: per frame, the pose of the marker numbered ``marker`` (when None, the
    lowest number decoded in the first frame holding any), relative to the marker numbered
    ``reference`` when one is named — at the scale ``pixel_um`` when it is given
    (:func:`relative`). ``workers`` and ``details`` are accepted for the layouts'
    common signature; markers are decoded one after the other."""
    found = decode_markers(frames, pattern, pixel_um)
    if marker is None:
        ok = found.status == "ok"
        numbers = sorted(set(found.number[ok].tolist()) - {reference})
        if not numbers:  # every frame: NaN, with its own status and reason
            return found.of(None)
        first_frame = int(found.frame[ok & np.isin(found.number, numbers)].min())
        here = found.number[(found.frame == first_frame) & ok]
        marker = int(min(set(here.tolist()) - {reference}))
    if reference is None:
        return found.of(marker)
    return relative(found, marker, reference, pattern.period_um, pixel_um)
