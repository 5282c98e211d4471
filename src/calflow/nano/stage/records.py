"""High-rate records of the simulated nano rigs (:mod:`calflow.nano.stage.rig`): ``stream`` samples a
dwell, ``record_move`` a move from its start (the closed loop's step response, ISO 9283 7.5,
7.6), as an interferometer's 1 kHz output or a controller's data recorder would.

Lengths in um, temperatures in degC, time in s. A mixin of the rig: it reads the rig's
physics (``_state``), noise (``_noise_sd``) and quantisation, and its virtual clock.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping

import numpy as np

__all__ = ["HighRateRecords"]


class HighRateRecords:
    """``stream`` and ``record_move`` of a simulated nano rig (module docstring)."""

    def stream(
        self, seconds: float, rate_hz: float | None = None, chunk: int = 4096
    ) -> Iterator[dict[str, np.ndarray]]:
        """Dwell ``seconds`` sampling at ``rate_hz`` (default option ``stream_rate_hz``).

        Advances the virtual clock by ``seconds`` at once and returns an iterator of chunk
        dicts of numpy arrays (``time`` and every sensor and thermometer, at most ``chunk``
        samples each); sample i is taken at ``t0 + (i + 1) / rate_hz``. Each call draws its
        noise from its own child seed, so interleaving reads does not change it. Reduce
        with :func:`calflow.acquisition.streams.reduce_dwell` (last 5 s of each dwell, Sec. 5.3.2).
        """
        rate, n, rng = self._sampling("stream", seconds, rate_hz, chunk)
        t0, self._t = self._t, self._t + float(seconds)
        return self._stream_iter(t0, n, rate, int(chunk), self._snapshot(), rng)

    def record_move(
        self, command: Mapping[str, float], seconds: float, rate_hz: float | None = None, chunk: int = 4096
    ) -> Iterator[dict[str, np.ndarray]]:
        """``move`` and record the sensors from the move's start, like a controller's data
        recorder triggered by the move command (GCS ``DRT``): sample i at ``t0 + i / rate_hz``,
        t0 the start of the move, for ``seconds``, at ``rate_hz`` (default ``stream_rate_hz``).
        The clock ends ``max(rise_time_s, seconds)`` after t0; chunks as :meth:`stream`."""
        rate, n, rng = self._sampling("record_move", seconds, rate_hz, chunk)
        t0 = self._t
        self.move(command)
        self._t = max(self._t, t0 + float(seconds))
        return self._stream_iter(t0 - 1.0 / rate, n, rate, int(chunk), self._snapshot(), rng)

    def _sampling(self, what, seconds, rate_hz, chunk):
        """Checked rate (Hz), number of samples and the noise generator of one record."""
        self._check_open()
        rate = float(self.options["stream_rate_hz"] if rate_hz is None else rate_hz)
        if not (rate > 0 and float(seconds) >= 0 and int(chunk) > 0):
            raise ValueError(f"{self._NAME}: {what} needs seconds >= 0, rate_hz > 0, chunk > 0")
        return (
            rate,
            int(math.floor(float(seconds) * rate + 1e-9)),
            np.random.default_rng(self._ss_streams.spawn(1)[0]),
        )

    def _stream_iter(self, t0, n, rate, chunk, state, rng):
        for start in range(0, n, chunk):
            i = np.arange(start, min(n, start + chunk), dtype=float)
            t = t0 + (i + 1.0) / rate
            pos, temps = self._state(t, state)
            out = {"time": t}
            for k, name in enumerate(self.sensors):
                v = pos[k] + self._noise_sd(pos)[k] * rng.standard_normal(t.size)
                out[name] = np.round(v / self._q_um) * self._q_um
            for j, name in enumerate(self.thermometers):
                v = temps[..., j] + self._sig_c * rng.standard_normal(t.size)
                out[name] = np.round(v / self._q_c) * self._q_c
            yield out
