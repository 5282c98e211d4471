"""Export of XYΘ calibrations to controllers and users' code.

:mod:`.bundle` — the controller-neutral bundle (JSON parameters, CSV tables, provenance);
:mod:`.compensator` — :class:`Compensator`, the bundle's inverse for users' code;
:mod:`.controllers` — LinuxCNC and TwinCAT CNC per-axis compensation files;
:mod:`.verification` — closed-loop check of the exported files on the rig. docs/export.md.
"""

from calflow.xytheta.export.compensator import Compensator

__all__ = ["Compensator"]
