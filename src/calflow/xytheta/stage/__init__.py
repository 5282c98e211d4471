"""The simulated XYΘ stage: its physics, vision sensor, GCS emulation, oracle and error budget."""
