"""GCS 2.0 controller client over TCP or a serial line (pyserial, imported lazily).

Protocol per PI MS249E (C-863.12 User Manual v1.2.1): §8.2 syntax and multi-line replies,
§8.3 address prefix, §8 command reference, §8.7 error codes (see
:mod:`calflow.gcs.wire.protocol`). Rules this client follows:

* every read has a deadline and raises :class:`GCSTimeout` instead of hanging; after a
  communication timeout a late reply could be taken for the answer to the next command,
  so the link is marked out of sync and further commands raise :class:`GCSConnectionLost`
  until :meth:`GCSController.reconnect` (the single recovery path for the rig layer);
* after each non-query command the client asks ``ERR?`` and raises the mapped
  :class:`GCSControllerError` subclass, naming the command and the axis at fault;
* EOF, reset or a serial failure raise :class:`GCSConnectionLost`;
* one lock serialises request/reply pairs, so another thread may call :meth:`stop_all`.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from typing import Any

from tenacity import RetryError, Retrying, retry_if_exception_type, stop_after_attempt, wait_exponential

from calflow.gcs.emulation.datarecorder import RecorderCommands
from calflow.gcs.wire.protocol import (
    MOTION_STATUS,
    READY_STATUS,
    STOP_ALL,
    GCSConnectionLost,
    GCSError,
    GCSInvalidAxisError,
    GCSMotionTimeout,
    GCSProtocolError,
    GCSStoppedError,
    GCSTimeout,
    ReplyFramer,
    check_axis,
    check_text,
    error_from_code,
    format_command,
    format_pairs,
    parse_axis_values,
    parse_bool,
    parse_int,
    parse_ready,
    strip_address,
)
from calflow.gcs.wire.transport import DEFAULT_BAUD, DEFAULT_PORT, SerialTransport, TCPTransport, Transport  # noqa: F401

log = logging.getLogger("calflow.gcs")
Axes = str | Iterable[str] | None


def _axis_list(axes: Axes) -> list[str]:
    if axes is None:
        return []
    return [check_axis(axes)] if isinstance(axes, str) else [check_axis(a) for a in axes]


class GCSController(RecorderCommands):
    """A GCS 2.0 controller (e.g. C-863 Mercury, E-709/E-727 piezo) seen through a transport.

    The data recorder's commands (``DRC``, ``DRT``, ``DRL?``, ``DRR?``) come from
    :class:`calflow.gcs.emulation.datarecorder.RecorderCommands`.
    """

    def __init__(self, opener: Callable[[], Transport], timeout: float = 5.0) -> None:
        self.timeout = float(timeout)
        self._opener = opener
        self._lock = threading.RLock()
        self._framer = ReplyFramer()
        self._in_sync = True
        self._stops = 0
        self._axes: list[str] | None = None
        self._transport: Transport | None = opener()

    @classmethod
    def connect_tcp(cls, host: str, port: int = DEFAULT_PORT, timeout: float = 5.0) -> GCSController:
        return cls(lambda: TCPTransport(host, port, timeout), timeout)

    @classmethod
    def connect_serial(cls, port: str, baudrate: int = DEFAULT_BAUD, timeout: float = 5.0) -> GCSController:
        return cls(lambda: SerialTransport(port, baudrate, timeout), timeout)

    def close(self) -> None:
        with self._lock:
            if self._transport is not None:
                self._transport.close()
                self._transport = None

    def __enter__(self) -> GCSController:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def reconnect(self, max_tries: int = 5, backoff: float = 0.2, max_backoff: float = 10.0) -> int:
        """Reopen the link with exponential backoff; returns the number of tries used.

        Waits ``backoff * 2**k`` (capped at ``max_backoff``; tenacity) between tries and checks each
        new link with ``*IDN?``. Controller state (servo, referencing) survives a dropped
        link on real controllers, so a higher layer can resume where it stopped.
        """
        retrying = Retrying(
            stop=stop_after_attempt(max(1, max_tries)),
            wait=wait_exponential(multiplier=backoff, exp_base=2, max=max_backoff),
            retry=retry_if_exception_type((GCSConnectionLost, GCSTimeout, GCSProtocolError)),
            after=lambda state: log.warning(
                "reconnect try %d/%d failed: %s", state.attempt_number, max_tries, state.outcome.exception()
            ),
        )
        try:
            retrying(self._reopen)
        except RetryError as err:
            last = err.last_attempt.exception()
            self._in_sync = False
            raise GCSConnectionLost(f"could not reconnect after {max_tries} tries: {last}") from last
        log.info("GCS link re-established after %d tries", retrying.statistics["attempt_number"])
        return retrying.statistics["attempt_number"]

    def _reopen(self) -> None:
        """One try of :meth:`reconnect`: a new link, checked with ``*IDN?``."""
        with self._lock:
            self.close()
            self._framer.clear()
            self._transport = self._opener()
            self._in_sync = True
            self.idn()

    # ------------------------------------------------------------------ transactions
    def _io(self) -> Transport:
        if self._transport is None:
            raise GCSConnectionLost("not connected (closed); call reconnect()")
        if not self._in_sync:
            raise GCSConnectionLost("link out of sync after a timeout; call reconnect()")
        return self._transport

    def _read_reply(self, command: str, timeout: float | None = None) -> list[str]:
        io = self._io()
        limit = self.timeout if timeout is None else timeout
        deadline = time.monotonic() + limit
        while (reply := self._framer.pop()) is None:
            left = deadline - time.monotonic()
            try:
                if left <= 0:
                    raise GCSTimeout("deadline passed")
                self._framer.feed(io.read(left))
            except GCSTimeout:
                self._in_sync = False
                raise GCSTimeout(f"no reply to {command!r} within {limit} s", command=command) from None
            except GCSConnectionLost as exc:
                self._in_sync = False
                raise GCSConnectionLost(
                    f"{exc} (while waiting for reply to {command!r})", command=command
                ) from None
        reply[0] = strip_address(reply[0])
        return reply

    def _send(self, data: bytes) -> None:
        io = self._io()
        if self._framer.pending():  # stale bytes cannot belong to the next request
            log.warning("discarding unexpected controller output before a new command")
            self._framer.clear()
        try:
            io.write(data)
        except GCSConnectionLost:
            self._in_sync = False
            raise

    def query(self, command: str, *args: object) -> list[str]:
        """Send a query (CMD?, *IDN?) and return its reply lines; no ERR? check."""
        with self._lock:
            self._send(format_command(command, args))
            return check_text(self._read_reply(command), command)

    def command(self, command: str, *args: object, axes: list[str] | None = None) -> None:
        """Send a non-query command, then ``ERR?``; raise the mapped error if non-zero.

        ``axes`` names the axes the command addresses, so errors can name the one at fault.
        """
        line = format_command(command, args)
        text = line.decode("ascii").strip()
        with self._lock:
            self._send(line)
            code = self.error_code()
        if code:
            raise error_from_code(code, command=text, axis=self._blame(code, text, axes or []))

    def error_code(self) -> int:
        """``ERR?``: the last error number, which the controller then resets to 0."""
        with self._lock:
            self._send(format_command("ERR?"))
            return parse_int(self._read_reply("ERR?"), command="ERR?")

    def _blame(self, code: int, text: str, axes: list[str]) -> str | None:
        """Name the axis at fault; for multi-axis commands ask the controller which one."""
        if len(axes) <= 1:
            return axes[0] if axes else None
        try:
            if code == 5:
                servo, ref = self.servo_state(axes), self.is_referenced(axes)
                return next((a for a in axes if not (servo[a] and ref[a])), None)
            if code == 15:
                return next((a for a in axes if a not in self.axes()), None)
            if code == 7 and text.startswith("MOV"):
                values = dict(zip(text.split()[1::2], map(float, text.split()[2::2])))
                lo, hi = self._values("TMN?", axes), self._values("TMX?", axes)
                return next((a for a in axes if not lo[a] <= values[a] <= hi[a]), None)
        except GCSError:
            pass
        return None

    def _values(
        self,
        query: str,
        axes: Axes = None,
        convert: Callable[[str], Any] = float,
    ) -> dict[str, Any]:
        names = _axis_list(axes)
        known = self.axes() if names else None
        for a in names:
            if known is not None and a not in known:  # the controller would not answer
                raise GCSInvalidAxisError(
                    f"invalid axis identifier {a!r} (controller has {known})", code=15, axis=a, command=query
                )
        return parse_axis_values(self.query(query, *names), convert, command=query, expect=names or None)

    def _pairs_command(self, mnemonic: str, pairs: Mapping[str, float | int]) -> None:
        """``MNEMONIC ax1 val1 ax2 val2`` (MOV, VEL, SVO) followed by the ERR? check."""
        self.command(mnemonic, *format_pairs(mnemonic, pairs).decode("ascii").split()[1:], axes=list(pairs))

    def _single(self, byte: bytes, name: str) -> list[str]:
        with self._lock:
            self._send(byte)
            return self._read_reply(name)

    # ------------------------------------------------------------------ identification
    def idn(self) -> str:
        return " ".join(self.query("*IDN?")).strip()

    def syntax_version(self) -> str:
        return self.query("CSV?")[0].strip()

    def help(self) -> str:
        return "\n".join(self.query("HLP?"))

    def axes(self) -> list[str]:
        """``SAI?``: axis identifiers (cached after the first call)."""
        if self._axes is None:
            self._axes = [check_axis(a.strip()) for a in self.query("SAI?") if a.strip()]
        return list(self._axes)

    # ------------------------------------------------------------------ servo / reference
    def servo_on(self, axes: Axes) -> None:
        self.set_servo({a: True for a in _axis_list(axes)})

    def servo_off(self, axes: Axes) -> None:
        self.set_servo({a: False for a in _axis_list(axes)})

    def set_servo(self, states: Mapping[str, bool]) -> None:
        self._pairs_command("SVO", {check_axis(a): int(bool(s)) for a, s in states.items()})

    def servo_state(self, axes: Axes = None) -> dict[str, bool]:
        return self._values("SVO?", axes, parse_bool)

    def reference(
        self, axes: Axes, *, method: str = "FRF", wait: bool = True, timeout: float = 60.0, poll: float = 0.05
    ) -> None:
        """Reference axes with FRF (reference switch) or FNL/FPL (limit switches).

        With ``wait``, polls ``#7`` until the controller is ready again and checks ``FRF?``.
        """
        if method not in ("FRF", "FNL", "FPL"):
            raise ValueError(f"reference method must be FRF, FNL or FPL, not {method!r}")
        names = _axis_list(axes)
        self.command(method, *names, axes=names)
        if not wait:
            return
        deadline = time.monotonic() + timeout
        while not self.ready():
            if time.monotonic() > deadline:
                raise GCSMotionTimeout(f"{method} not finished after {timeout} s", command=method)
            time.sleep(poll)
        missing = [a for a, ok in self.is_referenced(names or None).items() if not ok]
        if missing:
            raise GCSError(
                f"{method} finished but axes {missing} are not referenced", command=method, axis=missing[0]
            )

    def is_referenced(self, axes: Axes = None) -> dict[str, bool]:
        return self._values("FRF?", axes, parse_bool)

    # ------------------------------------------------------------------ motion
    def move(self, targets: Mapping[str, float]) -> None:
        """``MOV``: absolute targets, e.g. ``{"1": 12.5}``; returns once the command is accepted."""
        if not targets:
            raise ValueError("move() needs at least one axis target")
        self._pairs_command("MOV", {check_axis(a): float(v) for a, v in targets.items()})

    def target(self, axes: Axes = None) -> dict[str, float]:
        return self._values("MOV?", axes)

    def position(self, axes: Axes = None) -> dict[str, float]:
        return self._values("POS?", axes)

    def on_target(self, axes: Axes = None) -> dict[str, bool]:
        return self._values("ONT?", axes, parse_bool)

    def velocity(self, axes: Axes = None) -> dict[str, float]:
        return self._values("VEL?", axes)

    def set_velocity(self, velocities: Mapping[str, float]) -> None:
        self._pairs_command("VEL", {check_axis(a): float(v) for a, v in velocities.items()})

    def limits(self, axes: Axes = None) -> dict[str, tuple[float, float]]:
        lo, hi = self._values("TMN?", axes), self._values("TMX?", axes)
        return {a: (lo[a], hi[a]) for a in lo}

    def parameter(self, axis: str, pid: int) -> float:
        """``SPA? <axis> <pid>``: one parameter's value (e.g. 0x36, the C-863's settling
        window in counts; 0x3F, its settling time in s; docs/gcs.md "Settling")."""
        name, text = check_axis(axis), f"0x{int(pid):X}"
        lines = check_text(self.query("SPA?", name, text), "SPA?")
        key, sep, value = lines[0].rpartition("=") if len(lines) == 1 else ("", "", "")
        if not sep or key.split() != [name, text]:
            raise GCSProtocolError(f"unexpected reply to 'SPA? {name} {text}': {lines!r}", command="SPA?")
        try:
            return float(value)
        except ValueError:
            raise GCSProtocolError(
                f"not a number in reply to 'SPA? {name} {text}': {value!r}", command="SPA?"
            ) from None

    def set_parameter(self, axis: str, pid: int, value: float) -> None:
        """``SPA <axis> <pid> <value>`` (volatile memory), then the ERR? check."""
        self.command("SPA", check_axis(axis), f"0x{int(pid):X}", float(value), axes=[axis])

    def wait_on_target(
        self, timeout: float = 30.0, poll: float = 0.05, axes: Axes = None
    ) -> dict[str, float]:
        """Poll ``ONT?`` until all axes are on target; return ``POS?``.

        Raises :class:`GCSMotionTimeout` (motion still running; it is not stopped),
        :class:`GCSStoppedError` if :meth:`stop_all`/:meth:`stop` ran meanwhile, or the
        mapped error if ``ERR?`` is non-zero once on target (e.g. a #24 from elsewhere).
        """
        stops = self._stops
        deadline = time.monotonic() + timeout
        while True:
            if self._stops != stops:
                raise GCSStoppedError(
                    "motion was stopped while waiting for on-target", code=10, command="ONT?"
                )
            if all(self.on_target(axes).values()):
                break
            if time.monotonic() > deadline:
                raise GCSMotionTimeout(
                    f"axes not on target after {timeout} s",
                    command="ONT?",
                    axis=",".join(_axis_list(axes)) or None,
                )
            time.sleep(poll)
        code = self.error_code()
        if code or self._stops != stops:
            raise error_from_code(code or 10, command="ONT?")
        return self.position(axes)

    def motion_status(self) -> int:
        """``#5``: bit mask of moving axes (bit 0 = first axis of ``SAI?``)."""
        return parse_int(self._single(MOTION_STATUS, "#5"), base=16, command="#5")

    def moving(self) -> dict[str, bool]:
        mask = self.motion_status()
        return {a: bool(mask >> i & 1) for i, a in enumerate(self.axes())}

    def ready(self) -> bool:
        """``#7``: True when the controller can execute a new command (not referencing)."""
        return parse_ready(self._single(READY_STATUS, "#7"))

    def stop_all(self) -> int:
        """``#24``: stop all axes at once. Returns the ERR? code it leaves (10 expected)."""
        with self._lock:
            self._send(STOP_ALL)
            self._stops += 1
            return self.error_code()

    def stop(self) -> int:
        """``STP``: like #24 but as a command line. Returns the ERR? code (10 expected)."""
        with self._lock:
            self._send(format_command("STP"))
            self._stops += 1
            return self.error_code()
