"""A camera over an encoded dot pattern as a position sensor (thesis Sec. 3.5.1, 4.3).

* :class:`Pattern` — the pattern: a periodic grid of dots whose missing dots spell two
  m-sequences; a plain JSON file another program can render or manufacture from.
* :class:`Camera` — a camera on a microscope that renders frames of it at a pose.
* :func:`decode` — frames → x, y (µm), Θ (degree) in the pattern frame, their standard
  uncertainties, a status and a reason, for a pattern of any layout (:mod:`.layouts`: calflow's
  ``cell2x2``, FEMTO-ST's ``megarena``, a lab's own).

docs/instruments.md describes the file format, the camera model and its sources, the decoder's
steps and its figures.
"""

from calflow.instruments.pattern.decode import STATUSES, Decoded
from calflow.instruments.pattern.decode import decode as _decode_cell2x2
from calflow.instruments.pattern.pattern import Pattern
from calflow.instruments.pattern.render import Camera

__all__ = ["STATUSES", "Camera", "Decoded", "Pattern", "decode"]


def decode(frames, pattern, camera=None, pixel_um=None, workers=None, details=False) -> Decoded:
    """Frames → poses for a pattern of any layout: calflow's ``cell2x2`` by
    :func:`calflow.instruments.pattern.decode.decode`, another through its registered decoder
    (:mod:`.layouts`), handed the camera's pixel size when a camera is given."""
    if getattr(pattern, "layout", "cell2x2") == "cell2x2":
        return _decode_cell2x2(frames, pattern, camera, pixel_um, workers, details)
    from calflow.instruments.pattern.layouts import decode_frames

    if pixel_um is None and camera is not None:
        pixel_um = camera.pixel_um
    return decode_frames(frames, pattern, pixel_um=pixel_um, workers=workers, details=details)
