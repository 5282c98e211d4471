"""The simulated piezo stages: physics, thermal network, interferometer, drift the thermocouples
do not see, records, emulation, budget."""
