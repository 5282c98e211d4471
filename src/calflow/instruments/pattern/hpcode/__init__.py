"""HP-code markers (André et al., IJCV 130, 2022): several numbered dot targets in one frame,
each with its pose; one marker's pose relative to another's (docs/instruments.md)."""

from calflow.instruments.pattern.hpcode.decode import Markers, decode, decode_markers, relative
from calflow.instruments.pattern.hpcode.pattern import HPCodePattern

__all__ = ["HPCodePattern", "Markers", "decode", "decode_markers", "relative"]
