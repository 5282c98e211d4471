"""HP-code markers (André et al., IJCV 130, 2022): several numbered dot targets in one frame,
each with its pose; one marker's pose relative to another's; one pixel size pooled over a
sequence (docs/instruments.md)."""

from calflow.instruments.pattern.hpcode.decode import Markers, decode, decode_markers, relative
from calflow.instruments.pattern.hpcode.pattern import HPCodePattern
from calflow.instruments.pattern.hpcode.scale import SequenceScale, at_scale, pool_pixel

__all__ = [
    "HPCodePattern",
    "Markers",
    "SequenceScale",
    "at_scale",
    "decode",
    "decode_markers",
    "pool_pixel",
    "relative",
]
