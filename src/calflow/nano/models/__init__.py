"""The nanopositioning models of Chapter 5: geometric, thermal, single, KMZ, run-time controllers."""
