"""Byte transports of the GCS client: a TCP socket or a serial line (pyserial, lazily).

Each read has a deadline (:class:`GCSTimeout`, never a hang); EOF, reset or a serial
failure raise :class:`GCSConnectionLost` (PI MS249E §8.2).
"""

from __future__ import annotations

import socket
from typing import Protocol

from calflow.gcs.wire.protocol import GCSConnectionLost, GCSError, GCSTimeout

DEFAULT_PORT = 50000
DEFAULT_BAUD = 115200


class Transport(Protocol):
    def write(self, data: bytes) -> None: ...
    def read(self, timeout: float) -> bytes: ...  # some bytes, or raise GCSTimeout
    def close(self) -> None: ...


class TCPTransport:
    """TCP socket to a controller's GCS port (PI controllers listen on 50000)."""

    def __init__(self, host: str, port: int = DEFAULT_PORT, timeout: float = 5.0) -> None:
        try:
            self._sock = socket.create_connection((host, port), timeout=timeout)
        except TimeoutError as exc:
            raise GCSTimeout(f"connecting to {host}:{port} timed out after {timeout} s") from exc
        except OSError as exc:
            raise GCSConnectionLost(f"cannot connect to {host}:{port}: {exc}") from exc
        self._sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.name = f"tcp://{host}:{port}"

    def write(self, data: bytes) -> None:
        try:
            self._sock.settimeout(5.0)
            self._sock.sendall(data)
        except OSError as exc:
            raise GCSConnectionLost(f"{self.name}: send failed: {exc}") from exc

    def read(self, timeout: float) -> bytes:
        try:
            self._sock.settimeout(max(timeout, 1e-4))
            data = self._sock.recv(4096)
        except TimeoutError:
            raise GCSTimeout(f"{self.name}: no reply within the timeout") from None
        except OSError as exc:
            raise GCSConnectionLost(f"{self.name}: connection lost: {exc}") from exc
        if not data:
            raise GCSConnectionLost(f"{self.name}: connection closed by the controller")
        return data

    def close(self) -> None:
        self._sock.close()


class SerialTransport:
    """RS-232/USB serial line via pyserial (``serial_for_url``: device path or URL)."""

    def __init__(self, port: str, baudrate: int = DEFAULT_BAUD, timeout: float = 5.0) -> None:
        try:
            import serial  # noqa: PLC0415 - optional dependency, imported lazily
        except ImportError as exc:  # pragma: no cover - depends on the environment
            raise GCSError("serial transport needs pyserial: pip install pyserial") from exc
        self._serial_exc = serial.SerialException
        try:
            self._ser = serial.serial_for_url(port, baudrate=baudrate, timeout=timeout, write_timeout=timeout)
        except (serial.SerialException, OSError) as exc:
            raise GCSConnectionLost(f"cannot open serial port {port}: {exc}") from exc
        self.name = f"serial:{port}@{baudrate}"

    def write(self, data: bytes) -> None:
        try:
            self._ser.write(data)
            self._ser.flush()
        except (self._serial_exc, OSError) as exc:
            raise GCSConnectionLost(f"{self.name}: write failed: {exc}") from exc

    def read(self, timeout: float) -> bytes:
        try:
            self._ser.timeout = max(timeout, 1e-4)
            data = self._ser.read(max(1, self._ser.in_waiting))
        except (self._serial_exc, OSError) as exc:
            raise GCSConnectionLost(f"{self.name}: read failed: {exc}") from exc
        if not data:
            raise GCSTimeout(f"{self.name}: no reply within the timeout")
        return data

    def close(self) -> None:
        self._ser.close()
