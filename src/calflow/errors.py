"""Errors that calflow reports to users as one line (file, field, what was expected)."""


class CalflowError(Exception):
    """A user-facing error: the message is one line and names what is wrong and where."""


class ConfigError(CalflowError):
    """A campaign or workflow configuration file is invalid."""


class DataError(CalflowError):
    """A data file does not follow the calflow data contract."""


class RigError(CalflowError):
    """A rig could not be loaded or failed during acquisition."""


class OptionError(RigError, ValueError):
    """A rig option has a value the rig cannot use (or is unknown to it).

    Carries the option's name, so the config check can name the key it came from
    (``rig.options.<option>`` or ``rig.runs.<run>.<option>``).
    """

    def __init__(self, option: str, expected: str, value=None, unknown: bool = False):
        self.option, self.expected, self.value, self.unknown = option, expected, value, unknown
        super().__init__(
            f"unknown option {option!r} ({expected})"
            if unknown
            else f"option {option!r}: expected {expected}, got {value!r}"
        )

    def at(self, file, where: str) -> str:
        """The one-line message naming ``file`` and the key ``<where>.<option>``."""
        if self.unknown:
            return f"{file}: unknown key '{where}.{self.option}' ({self.expected})"
        return f"{file}: key '{where}.{self.option}': expected {self.expected}, got {self.value!r}"


class UnknownOptionError(OptionError, TypeError):
    """An option the rig does not have (a ``TypeError``, as an unexpected keyword is)."""

    def __init__(self, option: str, expected: str):
        super().__init__(option, expected, unknown=True)
