"""The kit of a simulated stage: what every family's simulated rig shares, beside its physics.

A family declares its stage once — a frozen dataclass of the true physics whose defaults are
the options, and an :class:`~calflow.rigs.simulated.effects.Effects` table naming each effect,
the fields that switch it off, its source and whether a calflow model represents it — and
takes from here what follows from that declaration:

* :mod:`.effects` — the effects table, the ``unmodelled`` switch (one key turns off every
  effect no model represents), rig options with effects off, the effects a rig has on;
* :mod:`.checks` — the rig options checked against the declaration (one line naming the
  option and what was expected);
* :mod:`.campaign` — the physics options of a campaign whose stage is simulated, directly or
  behind an emulated controller;
* :mod:`.budget` — the error budget's replays (one effect off at a time) and their
  combination into per-effect contributions.

A stage behind an emulated controller is declared in
:mod:`calflow.gcs.emulation.campaign_emulator` (the controller's layer).

Nothing here names a robot family; the modules are imported one by one (this package's
``__init__`` imports nothing, so a light module such as :mod:`.campaign` stays light).
"""
