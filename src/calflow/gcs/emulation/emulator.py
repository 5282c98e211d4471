"""A GCS 2.0 controller emulator served over TCP on 127.0.0.1 (and optionally a pty).

Command semantics follow PI MS249E (C-863.12 User Manual v1.2.1): §8.2 syntax (several
commands per segment, commands split over segments, case-insensitive mnemonics, a line
that cannot be fully executed is not executed at all), §8 command reference (``*IDN?``,
``CSV?``, ``SAI?``, ``HLP?``, ``SVO``, ``FRF``/``FNL``/``FPL``, ``VEL``, ``MOV``, ``POS?``,
``ONT?``, ``TMN?``/``TMX?``, ``ERR?``, ``STP``, ``#5``, ``#7``, ``#24``) and §8.7 error
codes. ``ERR?`` returns and clears the last error of the controller (shared by all
connections). A failing *query* sends no reply and only sets the error, as real
controllers do. Motion timing comes from :mod:`calflow.gcs.emulation.axis`.

Fault injection (:class:`Faults`, changeable at runtime) drops connections, delays
replies, answers garbage, or refuses new connections, so client fault handling can be
tested without hardware. Manual use: ``python -m calflow.gcs.emulation.emulator --port 50000
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
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from calflow.gcs.emulation.controller import EmulatedController, TruePosition  # noqa: F401 (re-exported)
from calflow.gcs.wire.protocol import CommandFramer, is_query, split_command

log = logging.getLogger("calflow.gcs.emulation.emulator")
LOCALHOST = "127.0.0.1"
GARBAGE = b"\x00\x1b#~garbage~\x7f\n"


@dataclass
class Faults:
    """Runtime fault injection. Counters are consumed as faults fire.

    drop_after: answer this many more commands, then close the connection when the next
        one arrives (it is not executed). delay: seconds to wait before every reply.
    garbage: the next N replies are replaced by binary garbage. refuse: the next N new
        connections are closed right after accept. error: the next N motion commands
        (MOV, SVO, FRF, ...: lines that are not queries) are refused with GCS error
        ``error_code`` (default 5: servo off, as after a sensor or amplifier fault).
    """

    drop_after: int | None = None
    delay: float = 0.0
    garbage: int = 0
    refuse: int = 0
    error: int = 0
    error_code: int = 5


class GCSEmulator:
    """Threaded TCP server around an :class:`EmulatedController`, bound to 127.0.0.1 only."""

    def __init__(
        self,
        axes: Any = None,
        host: str = LOCALHOST,
        port: int = 0,
        faults: Faults | None = None,
        *,
        time_scale: float = 1.0,
        true_position: TruePosition | None = None,
        address_prefix: int | None = None,
        controller: EmulatedController | None = None,
    ) -> None:
        if host not in (LOCALHOST, "localhost"):
            raise ValueError(f"the GCS emulator binds to {LOCALHOST} only, not {host!r}")
        self.controller = controller or EmulatedController(
            axes, time_scale=time_scale, true_position=true_position
        )
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
            except TimeoutError:
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
            except TimeoutError:
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
                with self._lock:
                    refuse = (
                        self.faults.error > 0
                        and not is_query(split_command(line)[0])
                        and split_command(line)[0] not in ("#24", "STP")
                    )
                    self.faults.error -= int(refuse)
                if refuse:
                    log.info("fault: refusing %r with error %d", line, self.faults.error_code)
                    with self.controller.lock:
                        self.controller.error = self.faults.error_code
                    reply = None
                else:
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


def serve(config: Mapping[str, Any] | None = None, stop_event: threading.Event | None = None) -> None:
    """Run an emulator until Ctrl-C, ``stop_event`` or ``config['duration']`` seconds.

    config keys: host (127.0.0.1), port (50000), axes ("1,2", a list, or a mapping of axis
    name to :class:`AxisConfig` fields), time_scale (1.0), pty (False), duration (None).
    """
    cfg = dict(config or {})
    emu = GCSEmulator(
        axes=cfg.get("axes", "1"),
        host=cfg.get("host", LOCALHOST),
        port=int(cfg.get("port", 50000)),
        time_scale=float(cfg.get("time_scale", 1.0)),
    )
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
    p = argparse.ArgumentParser(
        prog="python -m calflow.gcs.emulation.emulator",
        description="Emulate a PI GCS 2.0 controller on 127.0.0.1.",
    )
    p.add_argument("--port", type=int, default=50000, help="TCP port (0 = any free port)")
    p.add_argument("--axes", default="1", help="comma-separated axis identifiers, e.g. 1,2")
    p.add_argument("--time-scale", type=float, default=1.0, help="simulation speed-up factor")
    p.add_argument("--duration", type=float, default=None, help="stop after N seconds")
    p.add_argument("--pty", action="store_true", help="also serve on a pseudo-terminal")
    a = p.parse_args(argv)
    serve({"port": a.port, "axes": a.axes, "time_scale": a.time_scale, "pty": a.pty, "duration": a.duration})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
