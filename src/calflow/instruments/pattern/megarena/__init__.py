"""The Megarena layout (André et al. 2020): a dot grid whose rows and columns one binary
m-sequence keeps or leaves out; its pattern file and its decoder (docs/instruments.md)."""

from calflow.instruments.pattern.megarena.decode import MegarenaDecoded, decode
from calflow.instruments.pattern.megarena.pattern import MegarenaPattern, code_bits, sequence

__all__ = ["MegarenaDecoded", "MegarenaPattern", "code_bits", "decode", "sequence"]
