"""The data contract between workflow steps: conventions, atomic I/O, validation and the
export bundle of a calibrated model (:mod:`.bundle`)."""

from calflow.data.io import open_dataset, write_dataset, write_json, write_text
from calflow.data.validate import validate_dataset, validate_file

__all__ = [
    "open_dataset",
    "write_dataset",
    "write_json",
    "write_text",
    "validate_dataset",
    "validate_file",
]
