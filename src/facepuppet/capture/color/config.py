"""Options of the colour tracker (:class:`~facepuppet.capture.color.tracker.ColorTracker`), grouped by concern.

Units: a *face unit* is the distance between the eye centres; crop pixels are ``measure.px`` per face unit;
scores are correlations of the feature intensity with the layout drawn as a face, in [-1, 1].
"""

from __future__ import annotations

from dataclasses import dataclass, field

from facepuppet.capture.color.rules import OUTLINE_PARTS
from facepuppet.capture.color.snakes import SnakeConfig
from facepuppet.filters import OneEuroConfig

__all__ = ["ColorTrackerConfig", "MeasureConfig", "FollowConfig", "AcquireConfig", "LandmarkConfig", "FilterConfig"]


@dataclass(frozen=True, kw_only=True)
class MeasureConfig:
    """What one frame's measurement reads (§3.2-3.3).

    Attributes
    ----------
    px : float
        Crop pixels per face unit: the work is proportional to its square.
    reestimate_every : int
        Followed frames between re-estimates of Eq. 1's weights by the colour network.
    reestimate_gain : float
        In (0, 1]: the share of the way from the weights in use to the network's re-estimate they move at each
        re-estimate (the light changes slowly; one crop's estimate also moves with the face's expression).
    eye_window : (float, float)
        Half width and half height (face units) of the window the eye centres are searched in.
    outline_parts : tuple of str
        Which features §3.2's rules read (:data:`~facepuppet.capture.color.rules.OUTLINE_PARTS`); the others keep
        the layout's curves. A part's rules are skipped anyway where the profile's shape models read it (its
        curves would be replaced); the snakes go with the lips' rules, the eyelid model with the eyes'.
    snake : SnakeConfig
        The lips' snakes (Eqs. 2-4).
    """

    px: float = 48.0
    reestimate_every: int = 15
    reestimate_gain: float = 0.3
    eye_window: tuple[float, float] = (0.3, 0.14)
    outline_parts: tuple[str, ...] = OUTLINE_PARTS
    snake: SnakeConfig = field(default_factory=lambda: SnakeConfig(iterations=5, samples=10, offset=1.5, step=1.0))

    def __post_init__(self):
        unknown = set(self.outline_parts) - set(OUTLINE_PARTS)
        if unknown:
            raise ValueError(f"outline_parts: unknown {sorted(unknown)}; known: {', '.join(OUTLINE_PARTS)}")
        if not 0.0 < self.reestimate_gain <= 1.0:
            raise ValueError(f"reestimate_gain must be in (0, 1], got {self.reestimate_gain}")


@dataclass(frozen=True, kw_only=True)
class FollowConfig:
    """Following a face found in the last frame, on the evidence of the face itself.

    The face is kept while its crop still matches the reference crop taken when it was found (the correlation of
    the alignment), the eyes are found now and then, its cheeks look like skin as they did when it was found (or
    the match is close), its size moves smoothly, and, checked now and then, it still looks somewhat like a face
    (a low bar: the profile's layout may be another performer's).

    Attributes
    ----------
    iterations : int
        Most steps of the face crop's alignment on the reference crop (ECC) per frame.
    scale : float
        Resolution of the crops aligned, as a fraction of the tracker's crop.
    frame_gain : float
        Gain of the filter on the eyes' correction of the followed face frame (1: no smoothing), divided by the
        light transform's gain (:attr:`~.measure.Placement.light_gain`: a dim frame brightened is noisier).
    max_misses : int
        Frames in a row without the eyes after which the face is searched afresh.
    min_correlation : float
        Least correlation of the aligned crop with the reference to keep following (ECC's criterion, zero-mean
        normalised, so a change of the light's level or contrast does not lower it).
    skinless_correlation : float
        Least correlation to keep following a crop whose cheeks do not look like skin (where they did when the face
        was found).
    check_every : int
        Frames between checks that the followed crop still looks like a face.
    min_followed_score : float
        Least likeness to a face (averaged over checks) to keep following.
    """

    iterations: int = 2
    scale: float = 0.35
    frame_gain: float = 0.3
    max_misses: int = 15
    min_correlation: float = 0.5
    skinless_correlation: float = 0.75
    check_every: int = 4
    min_followed_score: float = 0.1


@dataclass(frozen=True, kw_only=True)
class AcquireConfig:
    """Finding the face afresh from the skin model (§3.1).

    Attributes
    ----------
    min_score : float
        Least likeness to a face to acquire one.
    min_skinless_score : float
        Least likeness to a face of a crop whose cheeks do not look like skin.
    resize_cost : float
        When the face was just lost, candidates for finding it again are compared by their likeness to a face
        minus this times the absolute log ratio of their size to the lost frame's: a face does not change size
        between two frames, a frame over the whole head or over one eye may look like a face too.
    cascade : bool
        Also take candidates from the windows where OpenCV's face cascade finds a face's pattern of dark
        features (:mod:`~facepuppet.capture.color.detect`), so a skin-coloured scene is not taken for the face.
    unsupported_cost : float
        Where the cascade found faces, a candidate outside all their windows has its likeness lowered by this.
    """

    min_score: float = 0.15
    min_skinless_score: float = 0.3
    resize_cost: float = 0.3
    cascade: bool = True
    unsupported_cost: float = 0.15


@dataclass(frozen=True, kw_only=True)
class LandmarkConfig:
    """The landmark backend's help (MediaPipe, optional): placing the face where skin fails, calibrating anchors.

    Attributes
    ----------
    enabled : bool
        When the skin model finds no face (greyscale or colour-graded images, odd light), find it with the
        landmark backend if mediapipe and its model (``$FACEPUPPET_FACE_LANDMARKER``) are available. Only its
        eye positions are used, to place the face frame; the curves still come from §3's pipeline.
    model : str or None
        Path of the landmark backend's model; default ``$FACEPUPPET_FACE_LANDMARKER``.
    retry : int
        After the landmark backend found no face, frames to wait before asking it again (it is slow).
    min_score : float
        Least likeness to a face of a frame placed by the landmark backend (-1: trust the backend).
    anchor_calibration : float
        At the first acquisition, move the eye anchors toward the eye blobs of a crop whose layout sits on the
        eyes the landmark backend sees (:func:`~facepuppet.capture.color.eye_calibration.calibrated_anchors`) by
        this fraction of the way (0: never). One frame's evidence is weighed against the generic anchors.
    anchor_scale_limits : (float, float)
        Bounds of the calibration's scale change of the layout.
    anchor_noise_floor : float
        Face units an eye anchor must move by for the calibration to move the anchors at all.
    """

    enabled: bool = True
    model: str | None = None
    retry: int = 10
    min_score: float = -1.0
    anchor_calibration: float = 0.5
    anchor_scale_limits: tuple[float, float] = (0.85, 1.15)
    anchor_noise_floor: float = 0.03


@dataclass(frozen=True, kw_only=True)
class FilterConfig:
    """Smoothing over time (speed-adaptive One-Euro filters, :class:`~facepuppet.filters.OneEuro`).

    Attributes
    ----------
    enabled : bool
        Smooth the face frame and the curves over time.
    curve : OneEuroConfig
        Filter of each curve control point in face units (speeds in face units per second).
    lid : OneEuroConfig
        Filter of the eyelids' middle control points when the profile has an eyelid model: as steady as
        ``curve`` when still, quicker when moving, for a blink lasts a few frames; its speed estimate is quick
        too (``d_cutoff`` 4 Hz), so that the lid's velocity down and back up within a blink opens the filter.
    lip : OneEuroConfig
        Filter of the lip curves' control points (unless a shape model reads them): as steady as ``curve`` when
        still, opening faster with the speed (``beta``) and with a quicker speed estimate (``d_cutoff`` 2 Hz),
        for a mouth opens and closes within a few frames while talking.
    shape : OneEuroConfig or None
        Filter of the control points the profile's shape models read (lips, brows, eyes)
        (:mod:`~facepuppet.capture.color.shape_models`), whose readings are steadier than the rules' and whose
        lag costs more than their jitter; None passes them unfiltered.
    frame : OneEuroConfig
        Filter of the face frame (eye midpoint and eye-to-eye vector, in face units).
    """

    enabled: bool = True
    curve: OneEuroConfig = field(default_factory=lambda: OneEuroConfig(min_cutoff=0.3, beta=1.5, d_cutoff=1.0))
    lid: OneEuroConfig = field(default_factory=lambda: OneEuroConfig(min_cutoff=0.3, beta=10.0, d_cutoff=4.0))
    lip: OneEuroConfig = field(default_factory=lambda: OneEuroConfig(min_cutoff=0.3, beta=2.5, d_cutoff=2.0))
    shape: OneEuroConfig | None = field(default_factory=lambda: OneEuroConfig(min_cutoff=1.0, beta=10.0, d_cutoff=4.0))
    frame: OneEuroConfig = field(default_factory=lambda: OneEuroConfig(min_cutoff=1.0, beta=6.0, d_cutoff=1.0))


@dataclass(frozen=True, kw_only=True)
class ColorTrackerConfig:
    """Options of the colour tracker, one group per concern.

    Attributes
    ----------
    measure : MeasureConfig
    follow : FollowConfig
    acquire : AcquireConfig
    landmarks : LandmarkConfig
    filters : FilterConfig
    """

    measure: MeasureConfig = field(default_factory=MeasureConfig)
    follow: FollowConfig = field(default_factory=FollowConfig)
    acquire: AcquireConfig = field(default_factory=AcquireConfig)
    landmarks: LandmarkConfig = field(default_factory=LandmarkConfig)
    filters: FilterConfig = field(default_factory=FilterConfig)
