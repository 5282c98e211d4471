"""The data contract between workflow steps: conventions, atomic I/O, validation and the
export bundle of a calibrated model (:mod:`.bundle`)."""

__all__ = [
    "open_dataset",
    "write_dataset",
    "write_json",
    "write_text",
    "validate_dataset",
    "validate_file",
]


def __getattr__(name: str):
    """The names above, imported when first used (PEP 562): importing a submodule such as
    :mod:`.io` to write a text file then costs no xarray import (~0.3 s of CPU)."""
    if name in __all__[:4]:
        from calflow.data import io

        return getattr(io, name)
    if name in __all__[4:]:
        from calflow.data import validate

        return getattr(validate, name)
    raise AttributeError(f"module 'calflow.data' has no attribute {name!r}")
