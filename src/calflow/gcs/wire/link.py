"""The controllers of a ``gcs`` rig: how each is reached, held and made ready.

A :class:`Link` is one controller and the joints it drives. :func:`connection` opens it
over TCP or serial, :func:`lock_controllers` holds it exclusively while a rig drives it
(a stage moves one plan at a time, whatever the executor), and :func:`prepare` checks its
axes, sets parameters, servo, referencing and velocity (docs/gcs.md, "The gcs rig").
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from filelock import FileLock

from calflow.errors import RigError
from calflow.gcs import DEFAULT_BAUD, DEFAULT_PORT, GCSController, GCSError
from calflow.gcs.emulation.controller import parse_parameter_id

log = logging.getLogger("calflow.gcs.rig")


@dataclass
class Link:
    """One controller and the joints it drives (joint -> controller axis id)."""

    name: str
    ctl: GCSController
    joints: dict[str, str]

    @property
    def axes(self) -> list[str]:
        return list(self.joints.values())

    def joint_of(self, axis: str | None) -> str | None:
        return next((j for j, a in self.joints.items() if a == axis), None)


def connection(spec: Mapping[str, Any], timeout: float) -> tuple[tuple, str, Callable[[], GCSController]]:
    """(key, name, opener) of a controller given host/port or serial/baudrate."""
    host, serial = spec.get("host"), spec.get("serial")
    if (host is None) == (serial is None):
        raise RigError("gcs rig: each controller needs exactly one of 'host' (TCP) or 'serial'")
    if host is not None:
        port = int(spec.get("port") or DEFAULT_PORT)
        return (
            ("tcp", str(host), port),
            f"tcp://{host}:{port}",
            lambda: GCSController.connect_tcp(str(host), port, timeout),
        )
    baud = int(spec.get("baudrate") or DEFAULT_BAUD)
    return (
        ("serial", str(serial), baud),
        f"serial:{serial}",
        lambda: GCSController.connect_serial(str(serial), baud, timeout),
    )


def lock_controllers(names: list[str]) -> list[FileLock]:
    """Hold an exclusive lock per controller while a rig drives it.

    A stage moves one plan at a time: two acquisitions on the same controllers (e.g.
    two validation jobs that Snakemake runs in parallel) must take turns, whatever the
    executor. The locks are files in the temporary directory (filelock: ``flock`` on POSIX,
    ``msvcrt`` locking on the Windows PCs that drive many lab controllers), taken in sorted
    order (no deadlock), blocking until free, released on ``close`` or when the process dies.
    """
    import hashlib
    import tempfile

    held = []
    for name in names:
        digest = hashlib.sha1(name.encode()).hexdigest()[:16]
        lock = FileLock(Path(tempfile.gettempdir()) / f"calflow-gcs-{digest}.lock", thread_local=False)
        lock.acquire()
        held.append(lock)
    return held


def unlock(locks: list[FileLock]) -> None:
    for lock in locks:
        lock.release()


def prepare(
    link: Link,
    *,
    servo: bool,
    reference: bool,
    velocity: Mapping[str, float],
    timeout: float,
    poll: float,
    parameters: Mapping[str, Mapping[Any, float]],
) -> None:
    """Check the axes exist (SAI?), set parameters (SPA), servo on (SVO), FRF what is not
    referenced, set VEL."""
    ctl = link.ctl
    try:
        known = ctl.axes()
        for joint, axis in link.joints.items():
            if axis not in known:
                raise RigError(
                    f"gcs rig: axes.{joint}: controller {link.name} has no axis {axis!r} (SAI? lists {known})"
                )
        for joint, values in parameters.items():
            for pid, value in values.items() if joint in link.joints else ():
                ctl.set_parameter(link.joints[joint], parse_parameter_id(str(pid)), float(value))
        if servo:
            ctl.servo_on(link.axes)
        if reference:
            todo = [a for a, ok in ctl.is_referenced(link.axes).items() if not ok]
            if todo:
                log.info("gcs rig: %s: referencing axes %s (FRF)", link.name, todo)
                ctl.reference(todo, timeout=timeout, poll=poll)
        vel = {link.joints[j]: float(v) for j, v in velocity.items() if j in link.joints}
        if vel:
            ctl.set_velocity(vel)
    except GCSError as exc:
        raise RigError(
            f"gcs rig: preparing controller {link.name} (joints {', '.join(link.joints)}) failed: {exc}"
        ) from exc
