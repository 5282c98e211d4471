"""Drift the thermocouples do not see: heat sources off their paths, mechanical settling,
humidity, the thermocouples' own errors and the interferometer's non-thermal errors."""
