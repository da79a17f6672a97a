"""How the performer's key expressions are captured: :class:`ExamplesConfig` and its defaults."""

from __future__ import annotations

from dataclasses import dataclass, field

from facepuppet.pipeline.tracking import TrackerOptions

__all__ = ["ExamplesConfig", "NEUTRAL", "AUTO_METHODS", "MIN_MOTION", "MIN_SEPARATION", "BLEND_TOLERANCE"]

#: The name of the neutral face (source base S_B) among the key expressions' names.
NEUTRAL = "neutral"
#: How ``--auto`` turns the picked frames into key expressions (see :attr:`ExamplesConfig.auto_method`).
AUTO_METHODS = ("regress", "frames")
#: A key expression moving the points less (RMS) than this share of the median key expression barely moves.
MIN_MOTION = 0.15
#: Two key expressions differing (RMS) by less than this share of the smaller one's motion are too close.
MIN_SEPARATION = 0.3
#: ``--auto``: a key-model whose motion a blend of the kept ones matches within this share of its own motion
#: (RMS of the residual) is shown only together with them.
BLEND_TOLERANCE = 0.3


@dataclass(frozen=True, kw_only=True)
class ExamplesConfig:
    """Options of capturing the performer's key expressions (``facepuppet calibrate``).

    Attributes
    ----------
    tracker : TrackerOptions
        The tracker that makes the feature points (it must be the one ``animate`` will use).
    window : int
        Frames averaged per key expression.
    search : float
        Seconds either side of a mark (or of the frame ``--auto`` picked) searched for the steadiest window.
    min_score : float
        ``--auto``: a key-model whose blendshape score never reaches this is left out (and reported).
    min_motion : float
        A key expression whose RMS displacement from neutral is below ``min_motion`` times the median over all
        key expressions is reported as barely different from neutral (``--auto``: left out).
    min_separation : float
        Two key expressions whose difference (RMS) is below ``min_separation`` times the smaller of their
        displacements are reported as too close to tell apart.
    blend_tolerance : float
        ``--auto``: a key-model whose displacement a least-squares blend of the key-models already kept
        matches within ``blend_tolerance`` times its own size (Euclidean norms) is left out as shown only
        together with them.
    auto_method : {"regress", "frames"}
        ``--auto``: ``frames`` takes each key-model's points from the frames that show it best; ``regress``
        (default) separates expressions a performer shows together by fitting every frame's points as a blend
        of the blendshape scores, each key-model on the part of the face it moves, and takes the face at zero
        scores as neutral (:func:`facepuppet.pipeline.examples.auto.regress_picks`).
    """

    tracker: TrackerOptions = field(default_factory=TrackerOptions)
    window: int = 5
    search: float = 0.3
    min_score: float = 0.3
    min_motion: float = MIN_MOTION
    min_separation: float = MIN_SEPARATION
    blend_tolerance: float = BLEND_TOLERANCE
    auto_method: str = "regress"

    def __post_init__(self) -> None:
        if self.auto_method not in AUTO_METHODS:
            raise ValueError(f"auto_method must be 'regress' or 'frames', got {self.auto_method!r}")
        if self.window < 1:
            raise ValueError(f"window must be at least 1 frame, got {self.window}")
        if self.search < 0:
            raise ValueError(f"search must be >= 0 seconds, got {self.search}")
