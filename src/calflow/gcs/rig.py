"""The ``gcs`` rig: PI GCS 2.0 stages plus a sensor (docs/gcs.md, "The gcs rig").

Stages are driven with :class:`calflow.gcs.GCSController` (docs/gcs.md "Servo,
referencing, motion"); readings come from a sensor plug-in
(a family's, e.g. the XYΘ family's simulated vision sensor; docs/gcs.md "Sensor drivers") given the stages' actual
``POS?`` positions. At open: servo on, FRF for axes not referenced (``reference: true``).

Resilience (docs/gcs.md "What the client does on errors", "Resilience of the gcs rig"):

* a link failure (:class:`GCSConnectionLost`, :class:`GCSTimeout` — after which the client
  refuses to talk until ``reconnect()`` —, :class:`GCSProtocolError`, socket errors) is
  recovered by ``reconnect()`` with exponential backoff, then the interrupted operation
  runs again; ``MOV`` is idempotent, so an interrupted move is simply sent again, and a
  sample is returned once, so acquisition neither loses nor duplicates samples. After
  ``reconnect.tries`` recoveries of one operation the rig gives up with a
  :class:`RigError`;
* a controller error (``ERR?`` non-zero, e.g. 7 out of limits, 5 servo off) or a motion
  that does not settle in ``move_timeout_s`` sends ``#24`` (stop all) to every controller
  and raises :class:`RigError` naming the joint, axis, command and code. The acquisition
  journal keeps the samples already taken.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterator, Mapping
from typing import Any, TypeVar

import numpy as np
from tenacity import RetryError, Retrying, retry_if_exception_type, stop_after_attempt

from calflow.errors import RigError
from calflow.gcs import (
    DEFAULT_BAUD,
    DEFAULT_PORT,
    ERROR_NAMES,
    GCSConnectionLost,
    GCSController,
    GCSControllerError,
    GCSError,
    GCSMotionTimeout,
    GCSProtocolError,
    GCSTimeout,
)
from calflow.gcs.rig_records import RecordedMoves
from calflow.gcs.sensors import load_sensor
from calflow.gcs.wire.link import Link, connection, lock_controllers, prepare, unlock

log = logging.getLogger("calflow.gcs.rig")
T = TypeVar("T")
LINK_ERRORS = (GCSConnectionLost, GCSTimeout, GCSProtocolError, OSError)
RECONNECTING = "gcs rig: %s: %s failed (%s); reconnecting (%d/%d)"
RESUME = (
    "; the samples already taken are kept in the acquisition journal (<out>.journal): "
    "fix the cause and run the same command again to continue after the last one"
)


class GCSRig(RecordedMoves):
    """Rig protocol (docs/rigs.md) over GCS controllers, plus ``stream`` and ``record_move``
    (:mod:`calflow.gcs.rig_records`) on piezo controllers; build it with :func:`gcs`."""

    replayable = False  # a real rig is continued, not replayed, on resume

    def __init__(
        self,
        links: list[Link],
        sensor: Any,
        *,
        scale: Mapping[str, float],
        tries: int = 5,
        backoff_s: float = 0.2,
        max_backoff_s: float = 10.0,
        time_scale: float = 1.0,
        move_timeout_s: float = 60.0,
        poll_s: float = 0.02,
    ) -> None:
        self.links, self.sensor = links, sensor
        self.joints = tuple(j for link in links for j in link.joints)
        self.sensors = tuple(sensor.sensors)
        self.thermometers = tuple(sensor.thermometers)
        self.scale = {j: float(scale.get(j, 1.0)) for j in self.joints}
        self.tries, self.backoff_s, self.max_backoff_s = max(0, int(tries)), backoff_s, max_backoff_s
        self.time_scale, self.move_timeout_s, self.poll_s = time_scale, move_timeout_s, poll_s
        self.recoveries = 0  # link recoveries so far (for logs and tests)
        self.recorder: Mapping[str, float] = {}  # data recorder options (stream())
        self._recording = False
        self._closed = False
        self._t0 = time.monotonic()

    @property
    def controllers(self) -> dict[str, GCSController]:
        return {link.name: link.ctl for link in self.links}

    # ------------------------------------------------------------------ protocol
    def time(self) -> float:
        """Seconds since open, times ``time_scale`` (the emulator's simulation time)."""
        return (time.monotonic() - self._t0) * self.time_scale

    def move(self, command: Mapping[str, float]) -> None:
        """``MOV`` on every controller, then ``wait_on_target`` on each (docs/gcs.md)."""
        if self._closed:
            raise RigError("gcs rig: move() after close()")
        unknown = sorted(set(command) - set(self.joints))
        if unknown:
            raise RigError(f"gcs rig: command names joints {unknown}; the rig has {list(self.joints)}")
        started = self.time()
        plan = [
            (link, {a: float(command[j]) / self.scale[j] for j, a in link.joints.items() if j in command})
            for link in self.links
        ]
        plan = [(link, targets) for link, targets in plan if targets]
        for link, targets in plan:
            self._run(link, "MOV", lambda retry, link=link, t=targets: link.ctl.move(t))
        settled: dict[str, float] = {}
        for link, targets in plan:

            def settle(retry: bool, link: Link = link, t: dict = targets) -> dict[str, float]:
                if retry:  # the interrupted move is sent again: MOV is idempotent
                    link.ctl.move(t)
                return link.ctl.wait_on_target(timeout=self.move_timeout_s, poll=self.poll_s, axes=list(t))

            pos = self._run(link, "wait on target", settle)
            settled.update({j: pos[a] * self.scale[j] for j, a in link.joints.items() if a in pos})
        if hasattr(self.sensor, "moved"):  # e.g. a simulated sensor keeping its own clock
            self._sensor("moved", settled, started)

    def wait(self, seconds: float) -> None:
        """Dwell: real time, divided by ``time_scale``."""
        time.sleep(max(0.0, float(seconds)) / self.time_scale)

    def stream(self, seconds: float) -> Iterator[dict[str, np.ndarray]]:
        """Dwell ``seconds`` and return the dwell's high-rate samples, one chunk.

        The data recorder of the first controller is the clock (``DRC`` current position
        of its axes, ``RTR`` for ``recorder.rate_hz``, ``DRT 0 2 0``, ``DRR?``): its points
        are handed to the sensor's ``stream(times, positions)``. A sensor without ``stream``
        gives one reading at the end of the dwell.
        """
        if not hasattr(self.sensor, "stream"):
            self.wait(seconds)
            return iter([{k: np.array([v]) for k, v in self.read().items()}])
        link, rec = self.links[0], self.recorder
        tables = {i + 1: (a, 2) for i, a in enumerate(link.axes)}
        rate = max(1, round(1.0 / (float(rec.get("rate_hz", 10.0)) * float(rec.get("servo_cycle_s", 5e-5)))))
        if not self._recording:
            self._run(link, "DRC", lambda retry: link.ctl.configure_recorder(tables, rate))
            self._recording = True
        self._run(link, "DRT", lambda retry: link.ctl.arm_recorder(2))
        start = self.time()
        self.wait(seconds)
        # the recording started with DRT's ERR? check, before ``start``: after the dwell it
        # holds point 0 and the n points of the dwell, so DRR? asks for them without DRL?
        n = int(np.floor(seconds / (rate * float(rec.get("servo_cycle_s", 5e-5))) + 1e-9))
        header, data = self._run(link, "DRR?", lambda retry: link.ctl.read_recorder(tables, 1, n + 1))
        dt = float(header.get("SAMPLE_TIME", rate * 5e-5))
        n = min(len(data) - 1, int(np.floor(seconds / dt + 1e-9)))
        times = start + dt * np.arange(1, n + 1)
        positions = {
            link.joint_of(a): data[1 : n + 1, i] * self.scale[link.joint_of(a)]
            for i, a in enumerate(link.axes)
        }
        values = self._sensor("stream", times, positions)
        return iter(
            [
                {
                    "time": times,
                    **{k: np.asarray(values[k], dtype=float) for k in (*self.sensors, *self.thermometers)},
                }
            ]
        )

    def positions(self) -> dict[str, float]:
        """Actual joint positions (``POS?``) in rig units (µm, degree)."""
        out: dict[str, float] = {}
        for link in self.links:
            pos = self._run(link, "POS?", lambda retry, link=link: link.ctl.position(link.axes))
            out.update({j: pos[a] * self.scale[j] for j, a in link.joints.items()})
        return out

    def read(self) -> dict[str, float]:
        """``time`` (s since open), each sensor and thermometer, read at ``POS?``."""
        if self._closed:
            raise RigError("gcs rig: read() after close()")
        positions = self.positions()
        now = self.time()
        values = self._sensor("read", positions, now)
        return {"time": now, **{k: float(values[k]) for k in (*self.sensors, *self.thermometers)}}

    def _sensor(self, method: str, *args: Any) -> Any:
        try:
            return getattr(self.sensor, method)(*args)
        except RigError as exc:  # a sensor driver's failure (e.g. the camera is gone)
            raise RigError(f"gcs rig: sensor: {exc}" + RESUME) from exc

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        if hasattr(self.sensor, "close"):
            self.sensor.close()
        for link in self.links:
            link.ctl.close()
        unlock(getattr(self, "_locks", []))

    # ------------------------------------------------------------------ resilience
    def _run(self, link: Link, what: str, op: Callable[[bool], T]) -> T:
        """Run ``op(retry)`` on ``link``; recover link failures, fail on controller errors.

        A link failure (``LINK_ERRORS``) is retried up to ``tries`` times (tenacity): after
        the k-th, wait ``backoff_s * 2**(k-1)`` (none after the first, capped at
        ``max_backoff_s``), reconnect, and run ``op(True)`` again."""
        last: list[Exception] = []
        retrying = Retrying(
            stop=stop_after_attempt(self.tries + 1),
            wait=self._wait_before_recovery,
            retry=retry_if_exception_type(LINK_ERRORS),
            before_sleep=lambda s: log.warning(
                RECONNECTING, link.name, what, s.outcome.exception(), s.attempt_number, self.tries
            ),
        )
        try:
            for attempt in retrying:
                with attempt:
                    if last:
                        self._recover(link, what, last[-1])
                    try:
                        return op(bool(last))
                    except GCSMotionTimeout as exc:
                        self._fail(link, what, exc)
                    except LINK_ERRORS as exc:
                        last.append(exc)
                        raise
                    except GCSError as exc:  # GCSControllerError and other controller-side failures
                        self._fail(link, what, exc)
        except RetryError as err:
            exc = err.last_attempt.exception()
            raise RigError(
                f"gcs rig: {link.name}: {what} failed {err.last_attempt.attempt_number} times in a "
                f"row, giving up (last: {exc})" + RESUME
            ) from exc

    def _wait_before_recovery(self, state) -> float:
        """Seconds before the reconnect that follows the ``state.attempt_number``-th failure."""
        k = state.attempt_number
        return 0.0 if k == 1 else min(self.backoff_s * 2 ** (k - 1), self.max_backoff_s)

    def _recover(self, link: Link, what: str, exc: Exception) -> None:
        try:
            link.ctl.reconnect(
                max_tries=max(1, self.tries), backoff=self.backoff_s, max_backoff=self.max_backoff_s
            )
        except GCSConnectionLost as lost:
            raise RigError(
                f"gcs rig: {link.name}: link lost during {what} and reconnecting failed: {lost}" + RESUME
            ) from exc
        self.recoveries += 1

    def stop_all(self) -> list[str]:
        """``#24`` on every controller; returns the names of those that could not be stopped."""
        failed = []
        for link in self.links:
            for attempt in range(2):
                try:
                    link.ctl.stop_all()
                    break
                except GCSError as exc:
                    if attempt:
                        log.error("gcs rig: %s: #24 failed: %s", link.name, exc)
                        failed.append(link.name)
                    else:
                        try:
                            link.ctl.reconnect(max_tries=2, backoff=self.backoff_s)
                        except GCSError:
                            pass
        return failed

    def _fail(self, link: Link, what: str, exc: GCSError) -> None:
        joint = link.joint_of(exc.axis)
        where = (
            f"joint {joint!r} (axis {exc.axis!r}"
            if joint
            else f"joints {', '.join(link.joints)} (axes {', '.join(link.axes)}"
        ) + f" on {link.name})"
        if isinstance(exc, GCSControllerError) and exc.code is not None:
            name = ERROR_NAMES.get(exc.code, ("", "unknown error"))[1]
            cause = f"command {exc.command or what!r} failed with GCS error {exc.code} ({name})"
        elif isinstance(exc, GCSMotionTimeout):
            cause = f"{what}: not on target within {self.move_timeout_s} s"
        else:
            cause = f"{what} failed: {exc}"
        failed = self.stop_all()
        stopped = "all axes stopped (#24)" if not failed else f"#24 could not be sent to {', '.join(failed)}"
        raise RigError(f"gcs rig: {where}: {cause}; {stopped}" + RESUME) from exc


def gcs(
    axes: Mapping[str, Any],
    host: str | None = None,
    port: int = DEFAULT_PORT,
    serial: str | None = None,
    baudrate: int = DEFAULT_BAUD,
    timeout: float = 5.0,
    sensor: Mapping[str, Any] | None = None,
    reconnect: Mapping[str, Any] | None = None,
    reference: bool = True,
    servo: bool = True,
    scale: Mapping[str, float] | None = None,
    velocity: Mapping[str, float] | None = None,
    time_scale: float = 1.0,
    move_timeout_s: float = 60.0,
    poll_s: float = 0.02,
    recorder: Mapping[str, float] | None = None,
    parameters: Mapping[str, Mapping[Any, float]] | None = None,
) -> GCSRig:
    """Factory of the ``gcs`` rig (docs/gcs.md, "The gcs rig").

    ``axes`` maps joint -> axis id on the controller at ``host``/``port`` (TCP) or
    ``serial``/``baudrate``, or joint -> ``{axis, host, port | serial, baudrate}`` for one
    controller per joint (the C-863 drives one axis). ``scale``: rig units (µm, degree)
    per controller unit, per joint (1000 for a stage in mm). ``velocity``: VEL per joint in
    controller units. ``reconnect``: ``{tries: 5, backoff_s: 0.2, max_backoff_s: 10}``.
    ``time_scale`` divides dwell times and multiplies reported time (emulators only).
    ``recorder``: ``{rate_hz: 10, servo_cycle_s: 5e-5}``, the data recorder's rate for
    :meth:`GCSRig.stream` (piezo controllers). ``parameters``: per joint, controller
    parameters set with ``SPA`` at open, e.g. ``{x: {"0x3F": 0.05}}`` (docs/gcs.md "Settling").
    """
    if not isinstance(axes, Mapping) or not axes:
        raise RigError("gcs rig: option 'axes' must map joint names to controller axis ids")
    if not time_scale > 0:
        raise RigError(f"gcs rig: time_scale must be > 0, got {time_scale!r}")
    shared = {"host": host, "port": port, "serial": serial, "baudrate": baudrate}
    groups: dict[tuple, tuple[str, Callable[[], GCSController], dict[str, str]]] = {}
    for joint, spec in axes.items():
        spec = {"axis": spec} if not isinstance(spec, Mapping) else dict(spec)
        if "axis" not in spec:
            raise RigError(f"gcs rig: axes.{joint}: missing 'axis' (the controller's axis id)")
        conn = {**shared, **{k: spec[k] for k in ("host", "port", "serial", "baudrate") if k in spec}}
        if ("host" in spec) != ("serial" in spec):  # a per-joint link replaces the shared one
            conn[("serial" if "host" in spec else "host")] = None
        key, name, opener = connection(conn, timeout)
        groups.setdefault(key, (name, opener, {}))[2][str(joint)] = str(spec["axis"])
    rc = dict(reconnect or {})
    sensor_obj = load_sensor(sensor)
    locks = lock_controllers(sorted(name for name, _, _ in groups.values()))
    links: list[Link] = []
    try:
        for name, opener, joints in groups.values():
            try:
                link = Link(name, opener(), joints)
            except GCSError as exc:
                raise RigError(f"gcs rig: cannot open controller {name}: {exc}") from exc
            links.append(link)
            prepare(
                link,
                servo=servo,
                reference=reference,
                velocity=velocity or {},
                timeout=move_timeout_s,
                poll=poll_s,
                parameters=parameters or {},
            )
    except BaseException:
        for link in links:
            link.ctl.close()
        unlock(locks)
        raise
    rig = GCSRig(
        links,
        sensor_obj,
        scale=scale or {},
        tries=rc.get("tries", 5),
        backoff_s=float(rc.get("backoff_s", 0.2)),
        max_backoff_s=float(rc.get("max_backoff_s", 10.0)),
        time_scale=float(time_scale),
        move_timeout_s=float(move_timeout_s),
        poll_s=float(poll_s),
    )
    rig._locks = locks
    rig.recorder = dict(recorder or {})
    return rig
