"""Implementations of the ``calflow`` subcommands, one module per concern."""
