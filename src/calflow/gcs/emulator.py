"""A GCS 2.0 controller emulator served over TCP on 127.0.0.1 (and optionally a pty).

Command semantics follow PI MS249E (C-863.12 User Manual v1.2.1): §8.2 syntax (several
commands per segment, commands split over segments, case-insensitive mnemonics, a line
that cannot be fully executed is not executed at all), §8 command reference (``*IDN?``,
``CSV?``, ``SAI?``, ``HLP?``, ``SVO``, ``FRF``/``FNL``/``FPL``, ``VEL``, ``MOV``, ``POS?``,
``ONT?``, ``TMN?``/``TMX?``, ``ERR?``, ``STP``, ``#5``, ``#7``, ``#24``) and §8.7 error
codes. ``ERR?`` returns and clears the last error of the controller (shared by all
connections). A failing *query* sends no reply and only sets the error, as real
controllers do. Motion timing comes from :mod:`calflow.gcs.axis`.

Fault injection (:class:`Faults`, changeable at runtime) drops connections, delays
replies, answers garbage, or refuses new connections, so client fault handling can be
tested without hardware. Manual use: ``python -m calflow.gcs.emulator --port 50000
--axes 1,2``.
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import select
import socket
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from calflow.gcs.axis import SimAxis, axis_configs
from calflow.gcs.protocol import NOT_READY, READY, CommandFramer, parse_bool, split_command

log = logging.getLogger("calflow.gcs.emulator")
LOCALHOST = "127.0.0.1"
GARBAGE = b"\x00\x1b#~garbage~\x7f\n"
TruePosition = Callable[[str, float], float]


@dataclass
class Faults:
    """Runtime fault injection. Counters are consumed as faults fire.

    drop_after: answer this many more commands, then close the connection when the next
        one arrives (it is not executed). delay: seconds to wait before every reply.
    garbage: the next N replies are replaced by binary garbage. refuse: the next N new
        connections are closed right after accept.
    """

    drop_after: int | None = None
    delay: float = 0.0
    garbage: int = 0
    refuse: int = 0


class _Err(Exception):
    """A GCS error code raised inside a handler; stored in the error register."""


class EmulatedController:
    """Controller state and GCS command semantics, independent of the transport."""

    HELP = ["*IDN?", "CSV?", "SAI? [ALL]", "HLP?", "ERR?", "SVO {<AxisID> <State>}", "SVO?",
            "FRF [{<AxisID>}]", "FNL [{<AxisID>}]", "FPL [{<AxisID>}]", "FRF?",
            "VEL {<AxisID> <Velocity>}", "VEL?", "MOV {<AxisID> <Position>}", "MOV?", "POS?",
            "ONT?", "TMN?", "TMX?", "STP", "#5", "#7", "#24"]

    def __init__(self, axes: Any = None, *, time_scale: float = 1.0,
                 true_position: TruePosition | None = None,
                 idn: str = "(c)2024 calflow, C-863.12-EMU, 0000000000, 0.1.0") -> None:
        if not time_scale > 0:
            raise ValueError("time_scale must be > 0")
        self.axes = {n: SimAxis(n, c) for n, c in axis_configs(axes).items()}
        self.time_scale, self.true_position, self.idn = float(time_scale), true_position, idn
        self.error = 0
        self.lock = threading.RLock()
        self._t0 = time.monotonic()

    def now(self) -> float:
        """Simulation time: wall-clock seconds since start times ``time_scale``."""
        return (time.monotonic() - self._t0) * self.time_scale

    # ------------------------------------------------------------------ dispatch
    def handle(self, line: str) -> list[str] | None:
        """Execute one command line; return reply lines, or None if nothing is sent."""
        name, args = split_command(line)
        with self.lock:
            now = self.now()
            try:
                reply = self._axis_query(name, args, now)
                if reply is not None:
                    return reply
                handler = getattr(self, "_q_" + name[:-1].lstrip("*")
                                  if name.endswith("?") else "_c_" + name.replace("#", "h"),
                                  None)
                if handler is None:
                    raise _Err(2)
                return handler(args, now)
            except _Err as exc:
                self.error = exc.args[0]
                return None

    def _select(self, args: list[str]) -> list[SimAxis]:
        for a in args:
            if a not in self.axes:
                raise _Err(15)
        return [self.axes[a] for a in args] if args else list(self.axes.values())

    def _pairs(self, args: list[str], conv: Callable[[str], Any]) -> list[tuple[SimAxis, Any]]:
        if not args or len(args) % 2:
            raise _Err(1)
        out = []
        for axis, raw in zip(args[0::2], args[1::2]):
            if axis not in self.axes:
                raise _Err(15)
            try:
                value = conv(raw)
            except ValueError:
                raise _Err(1) from None
            if isinstance(value, float) and not math.isfinite(value):
                raise _Err(1)
            out.append((self.axes[axis], value))
        return out

    @staticmethod
    def _answer(axes: Iterable[SimAxis], fn: Callable[[SimAxis], object]) -> list[str]:
        def fmt(v: object) -> str:
            return str(int(v)) if isinstance(v, bool) else f"{v:.6f}" if isinstance(v, float) \
                else str(v)
        return [f"{ax.name}={fmt(fn(ax))}" for ax in axes]

    # ------------------------------------------------------------------ queries
    def _q_IDN(self, args: list[str], now: float) -> list[str]:
        return [self.idn]

    def _q_CSV(self, args: list[str], now: float) -> list[str]:
        return ["2.0"]  # GCS syntax version (MS249E §8, CSV?)

    def _q_SAI(self, args: list[str], now: float) -> list[str]:
        if args and args != ["ALL"]:
            raise _Err(1)
        return list(self.axes)

    def _q_HLP(self, args: list[str], now: float) -> list[str]:
        return ["The following commands are available:", *self.HELP]

    def _q_ERR(self, args: list[str], now: float) -> list[str]:
        code, self.error = self.error, 0
        return [str(code)]

    def _axis_query(self, name: str, args: list[str], now: float) -> list[str] | None:
        """Per-axis queries answering ``axis=value`` (MS249E §8: SVO?, FRF?, POS?, ...)."""
        hook = self.true_position or (lambda axis, commanded: commanded)
        getters: dict[str, Callable[[SimAxis], object]] = {
            "SVO?": lambda ax: ax.servo,
            "FRF?": lambda ax: (ax.update(now), ax.referenced)[1],
            "VEL?": lambda ax: ax.velocity,
            "MOV?": lambda ax: ax.target(),
            "POS?": lambda ax: float(hook(ax.name, ax.position(now))),
            "ONT?": lambda ax: ax.on_target(now),
            "TMN?": lambda ax: float(ax.config.tmn),
            "TMX?": lambda ax: float(ax.config.tmx),
        }
        if name not in getters:
            return None
        return self._answer(self._select(args), getters[name])

    def _c_h5(self, args: list[str], now: float) -> list[str]:
        mask = sum(1 << i for i, ax in enumerate(self.axes.values()) if ax.moving(now))
        return [f"{mask:X}"]

    def _c_h7(self, args: list[str], now: float) -> list[str]:
        busy = any(ax.referencing(now) for ax in self.axes.values())
        return [NOT_READY if busy else READY]

    # ------------------------------------------------------------------ commands
    def _c_SVO(self, args: list[str], now: float) -> None:
        pairs = self._pairs(args, parse_bool)
        for ax, on in pairs:
            if not on and ax.moving(now):
                ax.stop(now)
            ax.servo = on

    def _c_FRF(self, args: list[str], now: float, where: str = "ref") -> None:
        """FRF: to the reference switch; FNL/FPL: to the negative/positive limit."""
        axes = self._select(args)
        if any(not ax.servo for ax in axes):
            raise _Err(5)
        for ax in axes:
            ax.reference(now, {"ref": None, "neg": ax.config.tmn, "pos": ax.config.tmx}[where])

    def _c_FNL(self, args: list[str], now: float) -> None:
        self._c_FRF(args, now, "neg")

    def _c_FPL(self, args: list[str], now: float) -> None:
        self._c_FRF(args, now, "pos")

    def _c_VEL(self, args: list[str], now: float) -> None:
        pairs = self._pairs(args, float)
        if any(not 0 < v <= ax.config.max_velocity for ax, v in pairs):
            raise _Err(8)
        for ax, v in pairs:
            ax.velocity = v

    def _c_MOV(self, args: list[str], now: float) -> None:
        pairs = self._pairs(args, float)
        if any(not ax.servo or not ax.referenced or ax.referencing(now) for ax, _ in pairs):
            raise _Err(5)
        if any(not ax.within_limits(v) for ax, v in pairs):
            raise _Err(7)
        for ax, v in pairs:
            ax.move(v, now)

    def _c_STP(self, args: list[str], now: float) -> None:
        if args:
            raise _Err(1)
        for ax in self.axes.values():
            ax.stop(now)
        self.error = 10  # MS249E: #24 and STP set error 10, PI_CNTR_STOP

    _c_h24 = _c_STP


class GCSEmulator:
    """Threaded TCP server around an :class:`EmulatedController`, bound to 127.0.0.1 only."""

    def __init__(self, axes: Any = None, host: str = LOCALHOST, port: int = 0,
                 faults: Faults | None = None, *, time_scale: float = 1.0,
                 true_position: TruePosition | None = None,
                 address_prefix: int | None = None) -> None:
        if host not in (LOCALHOST, "localhost"):
            raise ValueError(f"the GCS emulator binds to {LOCALHOST} only, not {host!r}")
        self.controller = EmulatedController(axes, time_scale=time_scale,
                                             true_position=true_position)
        self.faults = faults or Faults()
        self.address_prefix = address_prefix  # replies start "0 <n> " (MS249E §8.3)
        self.commands_handled = 0
        self._port = int(port)
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._sock: socket.socket | None = None
        self._threads: list[threading.Thread] = []
        self._conns: set[socket.socket] = set()
        self._fds: list[int] = []

    # ------------------------------------------------------------------ lifecycle
    @property
    def address(self) -> tuple[str, int]:
        if self._sock is None:
            raise RuntimeError("emulator not started")
        return LOCALHOST, self._sock.getsockname()[1]

    def start(self) -> GCSEmulator:
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((LOCALHOST, self._port))
        sock.listen(8)
        sock.settimeout(0.1)
        self._sock = sock
        self._spawn(self._accept_loop)
        log.info("GCS emulator listening on %s:%d", *self.address)
        return self

    def stop(self, timeout: float = 2.0) -> None:
        self._stop.set()
        self.drop_connections()
        if self._sock is not None:
            self._sock.close()
        for t in self._threads:
            t.join(timeout)
        while self._fds:
            os.close(self._fds.pop())

    def __enter__(self) -> GCSEmulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def drop_connections(self) -> None:
        """Close every open client connection now (the server keeps listening)."""
        with self._lock:
            conns, self._conns = list(self._conns), set()
        for c in conns:
            try:
                c.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            c.close()

    def _spawn(self, target: Callable[..., None], *args: Any) -> None:
        t = threading.Thread(target=target, args=args, daemon=True, name="gcs-emulator")
        self._threads = [*(x for x in self._threads if x.is_alive()), t]
        t.start()

    # ------------------------------------------------------------------ serving
    def _accept_loop(self) -> None:
        assert self._sock is not None
        while not self._stop.is_set():
            try:
                conn, _ = self._sock.accept()
            except (TimeoutError, socket.timeout):
                continue
            except OSError:
                return
            with self._lock:
                refuse = self.faults.refuse > 0
                self.faults.refuse -= int(refuse)
            if refuse:
                conn.close()
                continue
            conn.settimeout(0.1)
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            with self._lock:
                self._conns.add(conn)
            self._spawn(self._serve_socket, conn)

    def _serve_socket(self, conn: socket.socket) -> None:
        def recv() -> bytes | None:
            try:
                return conn.recv(4096)
            except (TimeoutError, socket.timeout):
                return None
        try:
            self._session(recv, conn.sendall)
        except OSError:
            pass
        except Exception:  # e.g. a failing true_position hook: show it, drop the link
            log.exception("GCS emulator session failed")
        finally:
            with self._lock:
                self._conns.discard(conn)
            conn.close()

    def _session(self, recv: Callable[[], bytes | None], send: Callable[[bytes], Any]) -> None:
        framer = CommandFramer()
        while not self._stop.is_set():
            data = recv()
            if data is None:
                continue
            if not data:
                return
            for line in framer.feed(data):
                with self._lock:
                    f = self.faults
                    drop = f.drop_after is not None and f.drop_after <= 0
                    if f.drop_after is not None:
                        f.drop_after = None if drop else f.drop_after - 1
                if drop:
                    log.info("fault: dropping connection at %r", line)
                    return
                reply = self.controller.handle(line)
                with self._lock:
                    self.commands_handled += 1
                if reply is None:
                    continue
                with self._lock:
                    delay, garbage = self.faults.delay, self.faults.garbage > 0
                    self.faults.garbage -= int(garbage)
                if delay > 0 and self._stop.wait(delay):
                    return
                send(GARBAGE if garbage else self._encode(reply))

    def _encode(self, lines: list[str]) -> bytes:
        if self.address_prefix is not None:
            lines = [f"0 {self.address_prefix} {lines[0]}", *lines[1:]]
        return (" \n".join(lines) + "\n").encode("latin-1")

    def serve_pty(self) -> str:
        """Also serve the controller on a pseudo-terminal; returns the device path for serial."""
        import tty

        master, slave = os.openpty()
        tty.setraw(slave)
        self._fds += [master, slave]  # keep the slave open so the master never sees EIO

        def recv() -> bytes | None:
            ready, _, _ = select.select([master], [], [], 0.1)
            try:
                return os.read(master, 4096) if ready else None
            except OSError:
                return b""
        self._spawn(self._session, recv, lambda b: os.write(master, b))
        return os.ttyname(slave)


def serve(config: Mapping[str, Any] | None = None,
          stop_event: threading.Event | None = None) -> None:
    """Run an emulator until Ctrl-C, ``stop_event`` or ``config['duration']`` seconds.

    config keys: host (127.0.0.1), port (50000), axes ("1,2", a list, or a mapping of axis
    name to :class:`AxisConfig` fields), time_scale (1.0), pty (False), duration (None).
    """
    cfg = dict(config or {})
    emu = GCSEmulator(axes=cfg.get("axes", "1"), host=cfg.get("host", LOCALHOST),
                      port=int(cfg.get("port", 50000)),
                      time_scale=float(cfg.get("time_scale", 1.0)))
    duration = cfg.get("duration")
    stop_event = stop_event or threading.Event()
    deadline = math.inf if duration is None else time.monotonic() + float(duration)
    with emu:
        host, port = emu.address
        print(f"GCS emulator on {host}:{port}, axes {', '.join(emu.controller.axes)}", flush=True)
        if cfg.get("pty"):
            print(f"serial (pty) device: {emu.serve_pty()}", flush=True)
        try:  # bounded waits so Ctrl-C is seen promptly
            while not stop_event.is_set() and (left := deadline - time.monotonic()) > 0:
                stop_event.wait(min(0.5, left))
        except KeyboardInterrupt:
            pass


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m calflow.gcs.emulator",
                                description="Emulate a PI GCS 2.0 controller on 127.0.0.1.")
    p.add_argument("--port", type=int, default=50000, help="TCP port (0 = any free port)")
    p.add_argument("--axes", default="1", help="comma-separated axis identifiers, e.g. 1,2")
    p.add_argument("--time-scale", type=float, default=1.0, help="simulation speed-up factor")
    p.add_argument("--duration", type=float, default=None, help="stop after N seconds")
    p.add_argument("--pty", action="store_true", help="also serve on a pseudo-terminal")
    a = p.parse_args(argv)
    serve({"port": a.port, "axes": a.axes, "time_scale": a.time_scale, "pty": a.pty,
           "duration": a.duration})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
