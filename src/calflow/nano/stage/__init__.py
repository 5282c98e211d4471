"""The simulated piezo stages: physics, thermal network, interferometer, records, emulation, budget."""
