"""The simulated hexapod: physics, laser tracker, C-887 emulation, workspace, error budget."""
