"""The joint commands a simulated rig's ``move`` and ``visit`` take, checked in one line."""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

from calflow.errors import RigError


def joint_commands(rig: str, call: str, closed: bool, joints: Iterable[str], command: Mapping) -> np.ndarray:
    """The commands of ``joints`` for ``call`` of the rig named ``rig``: a row (floats) for
    ``move``, columns (n, joints) of a plan's arrays for ``visit``. A :class:`RigError`
    naming the rig when it is ``closed`` or the command lacks a joint."""
    if closed:
        raise RigError(f"{rig}: {call}() after close()")
    try:
        if call == "visit":
            return np.column_stack([np.asarray(command[j], dtype=float) for j in joints])
        return np.array([float(command[j]) for j in joints])
    except KeyError as exc:
        raise RigError(f"{rig}: command lacks joint {exc.args[0]!r}") from None
