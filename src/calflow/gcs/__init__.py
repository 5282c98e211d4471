"""PI GCS 2.0 controller support: client, protocol and a controller emulator.

calflow talks to PI controllers (C-863 Mercury for the M-111 stage, piezo controllers for
the P-625) in GCS 2.0 ASCII itself; see ``docs/gcs.md``. The protocol follows PI's public
documentation (MS249E, C-863.12 User Manual, §8 "GCS Commands"); PI's ``pipython`` is not
used. The emulator (:mod:`calflow.gcs.emulation.emulator`) is imported on demand only.
"""

from calflow.gcs.wire.client import DEFAULT_BAUD, DEFAULT_PORT, GCSController, SerialTransport, TCPTransport
from calflow.gcs.wire.protocol import (
    ERROR_NAMES,
    GCSConnectionLost,
    GCSControllerError,
    GCSError,
    GCSInvalidAxisError,
    GCSMotionNotAllowedError,
    GCSMotionTimeout,
    GCSParameterSyntaxError,
    GCSPositionOutOfLimitsError,
    GCSProtocolError,
    GCSStoppedError,
    GCSTimeout,
    GCSUnknownCommandError,
    GCSVelocityOutOfLimitsError,
    error_from_code,
)

__all__ = [
    "DEFAULT_BAUD",
    "DEFAULT_PORT",
    "ERROR_NAMES",
    "GCSConnectionLost",
    "GCSController",
    "GCSControllerError",
    "GCSError",
    "GCSInvalidAxisError",
    "GCSMotionNotAllowedError",
    "GCSMotionTimeout",
    "GCSParameterSyntaxError",
    "GCSPositionOutOfLimitsError",
    "GCSProtocolError",
    "GCSStoppedError",
    "GCSTimeout",
    "GCSUnknownCommandError",
    "GCSVelocityOutOfLimitsError",
    "SerialTransport",
    "TCPTransport",
    "error_from_code",
]
