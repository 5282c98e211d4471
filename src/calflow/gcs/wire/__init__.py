"""How calflow talks to a PI GCS 2.0 controller (the wire): message framing, replies and
error codes (``protocol``), byte transports over TCP or a serial line (``transport``), the
client (``client``) and how a gcs rig reaches, holds and readies its controllers (``link``).
"""
