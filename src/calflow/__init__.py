"""calflow: reproducible calibration of micro- and nano-robotic positioning systems.

The method follows Tan, *Calibration of micro and nanorobotic systems* (thesis); equation
numbers in docstrings refer to it.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("calflow")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"

from calflow.moved import install as _serve_moved_paths

_serve_moved_paths()  # old import paths keep working for a release, with a warning (docs/api.md)

__all__ = ["__version__"]
