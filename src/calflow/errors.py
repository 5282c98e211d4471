"""Errors that calflow reports to users as one line (file, field, what was expected)."""


class CalflowError(Exception):
    """A user-facing error: the message is one line and names what is wrong and where."""


class ConfigError(CalflowError):
    """A campaign or workflow configuration file is invalid."""


class DataError(CalflowError):
    """A data file does not follow the calflow data contract."""


class RigError(CalflowError):
    """A rig could not be loaded or failed during acquisition."""
