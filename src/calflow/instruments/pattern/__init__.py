"""A camera over an encoded dot pattern as a position sensor (thesis Sec. 3.5.1, 4.3).

* :class:`Pattern` — the pattern: a periodic grid of dots whose missing dots spell two
  m-sequences; a plain JSON file another program can render or manufacture from.
* :class:`Camera` — a camera on a microscope that renders frames of it at a pose.
* :func:`decode` — frames → x, y (µm), Θ (degree) in the pattern frame, their standard
  uncertainties, a status and a reason.

docs/instruments.md describes the file format, the camera model and its sources, the decoder's
steps and its figures.
"""

from calflow.instruments.pattern.decode import STATUSES, Decoded, decode
from calflow.instruments.pattern.pattern import Pattern
from calflow.instruments.pattern.render import Camera

__all__ = ["STATUSES", "Camera", "Decoded", "Pattern", "decode"]
