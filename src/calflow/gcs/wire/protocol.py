"""GCS 2.0 message framing, reply parsing and error codes.

Implemented from PI's public GCS documentation, not from PI's ``pipython``:

* PI MS249E, *C-863.12 Mercury Controller User Manual* v1.2.1, §8.2 "GCS Syntax for
  Syntax Version 2.0": a command line is a mnemonic plus space-separated arguments ended
  by LF; the mnemonic is not case-sensitive; single-character commands (#5, #7, #24) are
  sent without terminator but answered with one; a multi-line reply ends every line but
  the last with "SP LF"; a query answers ``<Arg>=<Value>`` in the order asked; a command
  line of which any part cannot be executed is not executed at all.
* MS249E §8.3 "Target and Sender Address": replies may start with "<target> <sender> "
  (the PC is address 0), e.g. ``0 1 1=12.5``; :func:`strip_address` removes it.
* MS249E §8.7 "Error Codes": the controller error numbers reported by ``ERR?``.
* MS249E §8 "#5 (Request Motion Status)" (hex bit mask, bit 0 = first axis) and
  "#7 (Request Controller Ready Status)" (0xB1 ready, 0xB0 not ready).

Everything here is pure (no I/O) so it can be tested without sockets.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import TypeVar

from calflow.errors import RigError

ENCODING = "latin-1"  # the #7 reply is a single byte 0xB1/0xB0 (MS249E §8, #7)
LF = b"\n"
MOTION_STATUS = b"\x05"  # #5
READY_STATUS = b"\x07"  # #7
STOP_ALL = b"\x18"  # #24
SINGLE_BYTE_COMMANDS = {MOTION_STATUS[0]: "#5", READY_STATUS[0]: "#7", STOP_ALL[0]: "#24"}
READY, NOT_READY = "\xb1", "\xb0"

_AXIS_RE = re.compile(r"^[A-Za-z0-9_]{1,16}$")  # MS249E §8.2: alphanumerics and "_"
_ADDRESS_RE = re.compile(r"^0 \d{1,3} (?=\S)")  # MS249E §8.3: "<target=0> <sender> "

# MS249E §8.7 "Error Codes" (the controller errors the emulators and the client use).
ERROR_NAMES: dict[int, tuple[str, str]] = {
    0: ("PI_CNTR_NO_ERROR", "no error"),
    1: ("PI_CNTR_PARAM_SYNTAX", "parameter syntax error"),
    2: ("PI_CNTR_UNKNOWN_COMMAND", "unknown command"),
    3: ("PI_CNTR_COMMAND_TOO_LONG", "command length out of limits or command buffer overrun"),
    4: ("PI_CNTR_SCAN_ERROR", "error while scanning"),
    5: ("PI_CNTR_MOVE_WITHOUT_REF_OR_NO_SERVO", "motion not allowed: servo off or axis not referenced"),
    6: ("PI_CNTR_INVALID_SGA_PARAM", "parameter for SGA not valid"),
    7: ("PI_CNTR_POS_OUT_OF_LIMITS", "position out of limits"),
    8: ("PI_CNTR_VEL_OUT_OF_LIMITS", "velocity out of limits"),
    9: ("PI_CNTR_SET_PIVOT_NOT_POSSIBLE", "attempt to set pivot point while U,V and W not all 0"),
    10: ("PI_CNTR_STOP", "controller was stopped by command (#24/STP)"),
    11: ("PI_CNTR_SST_OR_SCAN_RANGE", "parameter for SST or scan algorithm out of range"),
    12: ("PI_CNTR_INVALID_SCAN_AXES", "invalid axis combination for fast scan"),
    13: ("PI_CNTR_INVALID_NAV_PARAM", "parameter for NAV out of range"),
    14: ("PI_CNTR_INVALID_ANALOG_INPUT", "invalid analog channel"),
    15: ("PI_CNTR_INVALID_AXIS_IDENTIFIER", "invalid axis identifier"),
    16: ("PI_CNTR_INVALID_STAGE_NAME", "unknown stage name"),
    17: ("PI_CNTR_PARAM_OUT_OF_RANGE", "parameter out of range"),
    54: ("PI_CNTR_UNKNOWN_PARAMETER", "unknown parameter"),
    57: ("PI_CNTR_INVALID_RECORDER_CHAN", "data record table does not exist"),
    58: ("PI_CNTR_INVALID_RECORDER_SRC_OPT", "source does not exist; number too low or too high"),
    59: ("PI_CNTR_INVALID_RECORDER_SRC_CHAN", "source record table number too low or too high"),
    60: ("PI_CNTR_PARAM_PROTECTION", "protected parameter: cannot be changed"),
}


# --------------------------------------------------------------------------- exceptions
class GCSError(RigError):
    """Base of every GCS failure. ``code`` is the GCS error number (None if not from ERR?)."""

    def __init__(
        self, message: str, *, code: int | None = None, axis: str | None = None, command: str | None = None
    ) -> None:
        super().__init__(message)
        self.code, self.axis, self.command = code, axis, command


class GCSTimeout(GCSError, TimeoutError):
    """No (complete) reply within the read timeout."""


class GCSMotionTimeout(GCSTimeout):
    """Axes did not reach their target in time (communication itself is fine)."""


class GCSConnectionLost(GCSError, ConnectionError):
    """The link was closed or reset (EOF, ECONNRESET, serial failure) or is out of sync."""


class GCSProtocolError(GCSError):
    """A reply that does not follow the GCS 2.0 syntax (garbage, wrong axes, bad number)."""


class GCSControllerError(GCSError):
    """The controller reported a non-zero error code via ``ERR?`` (MS249E §8.7)."""


class GCSParameterSyntaxError(GCSControllerError):
    """Error 1, PI_CNTR_PARAM_SYNTAX."""


class GCSUnknownCommandError(GCSControllerError):
    """Error 2, PI_CNTR_UNKNOWN_COMMAND."""


class GCSMotionNotAllowedError(GCSControllerError):
    """Error 5: motion not allowed, servo off or axis not referenced."""


class GCSPositionOutOfLimitsError(GCSControllerError):
    """Error 7, PI_CNTR_POS_OUT_OF_LIMITS (target outside TMN?..TMX?)."""


class GCSVelocityOutOfLimitsError(GCSControllerError):
    """Error 8, PI_CNTR_VEL_OUT_OF_LIMITS."""


class GCSStoppedError(GCSControllerError):
    """Error 10, PI_CNTR_STOP: motion was stopped by #24 or STP."""


class GCSInvalidAxisError(GCSControllerError):
    """Error 15, PI_CNTR_INVALID_AXIS_IDENTIFIER."""


ERROR_CLASSES: dict[int, type[GCSControllerError]] = {
    1: GCSParameterSyntaxError,
    2: GCSUnknownCommandError,
    5: GCSMotionNotAllowedError,
    7: GCSPositionOutOfLimitsError,
    8: GCSVelocityOutOfLimitsError,
    10: GCSStoppedError,
    15: GCSInvalidAxisError,
}


def error_from_code(code: int, *, command: str | None = None, axis: str | None = None) -> GCSControllerError:
    """Build the exception for GCS error ``code``; unknown codes give a plain GCSControllerError."""
    name, text = ERROR_NAMES.get(code, ("UNKNOWN", f"unknown GCS error code {code}"))
    where = "".join([f", command {command!r}" if command else "", f", axis {axis!r}" if axis else ""])
    msg = f"GCS error {code} ({name}): {text}{where}"
    return ERROR_CLASSES.get(code, GCSControllerError)(msg, code=code, axis=axis, command=command)


# --------------------------------------------------------------------------- commands
def check_axis(axis: object) -> str:
    """Return ``axis`` as str if it is a valid GCS axis identifier (MS249E §8.2), else raise."""
    name = str(axis)
    if not _AXIS_RE.match(name):
        raise ValueError(f"invalid GCS axis identifier {name!r} (1-16 of A-Z a-z 0-9 _)")
    return name


def format_number(value: float) -> str:
    """Format a float argument: finite, no exponent surprises for the controller."""
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"GCS argument must be finite, got {value!r}")
    text = f"{v:.10f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def format_command(mnemonic: str, args: Iterable[object] = ()) -> bytes:
    """Encode one command line ``MNEMONIC arg arg...LF`` (MS249E §8.2)."""
    parts = [mnemonic, *(format_number(a) if isinstance(a, float) else str(a) for a in args)]
    line = " ".join(parts)
    if any(ch in line for ch in "\n\r") or any(ord(ch) < 32 for ch in line):
        raise ValueError(f"control character in GCS command {line!r}")
    return line.encode("ascii") + LF


def format_pairs(mnemonic: str, values: Mapping[str, object]) -> bytes:
    """Encode ``MNEMONIC ax1 val1 ax2 val2 ...`` (e.g. MOV, VEL, SVO)."""
    args: list[object] = []
    for axis, value in values.items():
        args += [check_axis(axis), int(value) if isinstance(value, int) else float(value)]
    return format_command(mnemonic, args)


def is_query(mnemonic: str) -> bool:
    """True for commands that answer (CMD?, *IDN?, #5, #7); #24 is not a query."""
    return mnemonic.endswith("?") or mnemonic in ("#5", "#7")


# --------------------------------------------------------------------------- framing
@dataclass
class ReplyFramer:
    """Reassembles replies from a byte stream: a reply ends with a LF not preceded by SP.

    ``feed()`` accepts arbitrary chunks (a reply split over TCP segments, or several replies
    in one segment); ``pop()`` returns the lines of the next complete reply (continuation
    spaces removed) or None.
    """

    _buf: bytearray = field(default_factory=bytearray)
    _lines: list[str] = field(default_factory=list)
    _done: list[list[str]] = field(default_factory=list)

    def feed(self, data: bytes) -> None:
        self._buf += data
        while (i := self._buf.find(LF)) >= 0:
            raw = bytes(self._buf[:i]).rstrip(b"\r")
            del self._buf[: i + 1]
            cont = raw.endswith(b" ")
            self._lines.append(raw[:-1].decode(ENCODING) if cont else raw.decode(ENCODING))
            if not cont:
                self._done.append(self._lines)
                self._lines = []

    def pop(self) -> list[str] | None:
        return self._done.pop(0) if self._done else None

    def pending(self) -> bool:
        """True if bytes of an incomplete reply are buffered."""
        return bool(self._buf or self._lines or self._done)

    def clear(self) -> None:
        self._buf.clear()
        self._lines.clear()
        self._done.clear()


@dataclass
class CommandFramer:
    """Server side: splits a byte stream into command lines and single-byte commands.

    #5/#7/#24 are recognised anywhere in the stream (they are not LF-terminated,
    MS249E §8.2); other commands end with LF.
    """

    _buf: bytearray = field(default_factory=bytearray)
    max_line: int = 4096

    def feed(self, data: bytes) -> list[str]:
        out: list[str] = []
        for byte in data:
            if byte in SINGLE_BYTE_COMMANDS:
                out.append(SINGLE_BYTE_COMMANDS[byte])
            elif byte == LF[0]:
                line = self._buf.decode(ENCODING).strip("\r ")
                self._buf.clear()
                if line:
                    out.append(line)
            elif len(self._buf) < self.max_line:
                self._buf.append(byte)
        return out


def split_command(line: str) -> tuple[str, list[str]]:
    """Split a command line into (upper-case mnemonic, arguments)."""
    if line.startswith("#"):
        return line, []
    parts = line.split()
    return (parts[0].upper(), parts[1:]) if parts else ("", [])


# --------------------------------------------------------------------------- replies
def strip_address(line: str) -> str:
    """Remove a leading "0 <sender> " address (MS249E §8.3) from the first reply line."""
    return _ADDRESS_RE.sub("", line, count=1)


_GARBAGE_RE = re.compile("[\x00-\x08\x0a-\x1f\x7f-\x9f]")  # control characters but TAB


def check_text(lines: list[str], command: str | None = None) -> list[str]:
    """Reject replies containing control characters (line noise, binary garbage)."""
    for line in lines:
        if _GARBAGE_RE.search(line):
            raise GCSProtocolError(f"garbage in reply to {command!r}: {line!r}", command=command)
    return lines


T = TypeVar("T")


def parse_bool(text: str) -> bool:
    if text not in ("0", "1"):
        raise ValueError(f"expected 0 or 1, got {text!r}")
    return text == "1"


def parse_axis_values(
    lines: list[str],
    convert: Callable[[str], T] = float,  # type: ignore[assignment]
    *,
    command: str | None = None,
    expect: Iterable[str] | None = None,
) -> dict[str, T]:
    """Parse ``axis=value`` lines into a dict; with ``expect``, the axes must match exactly."""
    out: dict[str, T] = {}
    for line in check_text(lines, command):
        key, sep, value = line.strip().partition("=")
        try:
            if not sep:
                raise ValueError("no '='")
            out[check_axis(key.strip())] = convert(value.strip())
        except ValueError as exc:
            raise GCSProtocolError(
                f"cannot parse reply line {line!r} to {command!r}: {exc}", command=command
            ) from None
    if expect is not None and sorted(out) != sorted(expect):
        raise GCSProtocolError(
            f"reply to {command!r} names axes {sorted(out)}, expected {sorted(expect)}", command=command
        )
    return out


def parse_int(lines: list[str], *, base: int = 10, command: str | None = None) -> int:
    """Parse a single-line integer reply (ERR? decimal, #5 hex)."""
    check_text(lines, command)
    text = lines[0].strip() if len(lines) == 1 else ""
    if base == 16 and text.lower().startswith("0x"):
        text = text[2:]
    try:
        return int(text, base)
    except ValueError:
        raise GCSProtocolError(
            f"expected one integer in reply to {command!r}, got {lines!r}", command=command
        ) from None


def parse_ready(lines: list[str]) -> bool:
    """Parse the #7 reply: 0xB1 ready, 0xB0 not ready."""
    text = lines[0].strip() if len(lines) == 1 else ""
    if text not in (READY, NOT_READY):
        raise GCSProtocolError(f"unexpected reply to #7: {lines!r}", command="#7")
    return text == READY
