"""Reduce raw high-rate rig streams to ``sample`` rows in bounded memory.

A stream is an iterable of chunk dicts of 1-D numpy arrays of equal length: ``time``
(s, non-decreasing across the whole stream) and one array per channel (sensors in um,
thermometers in degC). Thesis Sec. 5.3.2 takes, for each 25 s dwell of the training
trajectory (Fig. 5.8), the average of the last 5 s as the measurement: that is
:func:`reduce_dwell` with ``window_s=5.0``.

Memory: the reducer keeps only the samples that can still fall in the window (those
newer than ``t_last - window_s``) plus the chunk being processed, so a 14 h dwell at
1 kHz costs about ``window_s * rate * channels * 8`` bytes (5 s x 1 kHz x 7 channels
~ 0.3 MB), never the whole stream.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Mapping

import numpy as np

__all__ = ["DwellReducer", "reduce_dwell"]

_TIME_TOL_S = 1e-6  # samples exactly window_s before the last one are excluded


class DwellReducer:
    """Incremental mean of every channel over the last ``window_s`` seconds.

    Feed chunks with :meth:`update`; :meth:`row` gives the current result. The window is
    the half-open interval ``(t_last - window_s, t_last]`` (a 1e-6 s tolerance absorbs
    rounding of sample times), so 5 s at 10 Hz averages exactly 50 samples.
    """

    def __init__(self, window_s: float = 5.0):
        window_s = float(window_s)
        if not window_s > 0:
            raise ValueError(f"window_s must be > 0 s, got {window_s!r}")
        self.window_s = window_s
        self._channels: tuple[str, ...] | None = None
        self._pieces: deque[tuple[np.ndarray, np.ndarray]] = deque()  # (time, values[c, n])
        self._t_last = -np.inf

    def update(self, chunk: Mapping[str, np.ndarray]) -> None:
        """Add one chunk (dict of equal-length 1-D arrays including ``time``)."""
        if "time" not in chunk:
            raise ValueError("stream chunk has no 'time' array")
        t = np.asarray(chunk["time"], dtype=float)
        if t.ndim != 1:
            raise ValueError("stream chunk 'time' must be a 1-D array")
        names = tuple(k for k in chunk if k != "time")
        if self._channels is None:
            self._channels = names
        elif set(names) != set(self._channels):
            raise ValueError(
                f"stream chunk channels {sorted(names)} differ from the first "
                f"chunk's {sorted(self._channels)}"
            )
        if t.size == 0:
            return
        if t[0] < self._t_last or np.any(np.diff(t) < 0):
            raise ValueError("stream times must be non-decreasing")
        self._t_last = float(t[-1])
        start = self._t_last - self.window_s + _TIME_TOL_S
        keep = np.searchsorted(t, start, side="right")
        if keep < t.size:
            values = np.empty((len(self._channels), t.size - keep))
            for c, name in enumerate(self._channels):
                v = np.asarray(chunk[name], dtype=float)
                if v.shape != t.shape:
                    raise ValueError(f"stream channel {name!r} has {v.shape} samples, time has {t.shape}")
                values[c] = v[keep:]
            self._pieces.append((t[keep:].copy(), values))
        # drop what the new last time pushed out of the window
        while self._pieces and self._pieces[0][0][-1] <= start:
            self._pieces.popleft()
        if self._pieces:
            t0, v0 = self._pieces[0]
            cut = np.searchsorted(t0, start, side="right")
            if cut:
                self._pieces[0] = (t0[cut:], v0[:, cut:])

    @property
    def n_kept(self) -> int:
        """Number of samples currently held (bounded by the window)."""
        return sum(p[0].size for p in self._pieces)

    def row(self) -> dict[str, float]:
        """Mean of each channel over the window, ``time`` of the last sample, ``n``."""
        n = self.n_kept
        if n == 0:
            raise ValueError("empty stream: nothing to reduce")
        totals = sum(v.sum(axis=1) for _, v in self._pieces)
        out: dict[str, float] = {"time": self._t_last}
        out.update({name: float(totals[c] / n) for c, name in enumerate(self._channels)})
        out["n"] = n
        return out


def reduce_dwell(chunks: Iterable[Mapping[str, np.ndarray]], window_s: float = 5.0) -> dict[str, float]:
    """One sample row from a dwell's stream: channel means over its last ``window_s`` s.

    Returns a dict of floats: every channel's mean over the samples with time in
    ``(t_last - window_s, t_last]``, ``time`` = time of the last sample (s) and ``n`` =
    number of samples averaged. Sec. 5.3.2: the last 5 s of each 25 s dwell. Memory is
    O(window) (see :class:`DwellReducer`); raises ``ValueError`` on an empty stream.
    """
    reducer = DwellReducer(window_s)
    for chunk in chunks:
        reducer.update(chunk)
    return reducer.row()
