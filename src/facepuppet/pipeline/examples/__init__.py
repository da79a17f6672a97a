"""Capturing the performer's key expressions (the paper's source base S_B and source examples S_i).

:func:`capture_examples` captures them from a video, by marks or automatically. The three ways, all
returning a :class:`~facepuppet.io.performer.Performer` (saved with
:func:`~facepuppet.io.performer.save_performer` as the key expressions file ``facepuppet rig --performer``
reads):

- :func:`from_marks` (:mod:`.marks`): a video and a marks file that names the key expression shown at a
  time or frame; the feature points are averaged over the steadiest few frames near each mark;
- :func:`from_auto` (:mod:`.auto`): for characters whose key-models carry ARKit names, the landmark backend's
  blendshape scores pick the frame that best shows each key-model, and the most relaxed frame as neutral;
- :func:`from_camera` (:mod:`.interactive`): live from a camera; the key-model's name and a picture of it
  are shown, the performer copies it and presses a key.

:func:`check_examples` (:mod:`.checks`) names key expressions too close to each other to tell apart, or
barely different from neutral; its findings are the Performer's ``warnings``. :class:`ExamplesConfig`
holds the options of all three.
"""

from facepuppet.pipeline.examples.auto import from_auto
from facepuppet.pipeline.examples.capture import capture_examples
from facepuppet.pipeline.examples.checks import check_examples
from facepuppet.pipeline.examples.config import NEUTRAL, ExamplesConfig
from facepuppet.pipeline.examples.interactive import CANCEL_KEYS, CAPTURE_KEYS, KeySource, from_camera
from facepuppet.pipeline.examples.marks import HEAD_MOTION, Mark, from_marked_track, from_marks, parse_when, read_marks
from facepuppet.pipeline.examples.window import steadiest_window

__all__ = [
    "capture_examples", "ExamplesConfig", "from_marks", "from_marked_track", "from_auto", "from_camera",
    "check_examples",
    "Mark", "read_marks", "parse_when", "steadiest_window", "KeySource", "CAPTURE_KEYS", "CANCEL_KEYS",
    "NEUTRAL", "HEAD_MOTION",
]
