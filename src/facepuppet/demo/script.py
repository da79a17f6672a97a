"""The demo's key-expression vocabulary and its scripted performances.

The demo drives 13 key expressions, as many as the paper's thirteen key-models (§6). Their names follow
Apple's ARKit blendshapes; a symmetric pair (``mouthSmileLeft``/``mouthSmileRight``) is one key here, and
:data:`ARKIT_NAMES` lists the ARKit names each key stands for.

Conventions: weights in [0, 1], one column per key in :data:`KEY_NAMES` order; head motion per frame is
``(yaw, pitch, roll, x, y, z)``: radians about the head's y (up), x (to the performer's left) and z (out of
the face) axes, and a translation in centimetres of the head in its neutral frame (see
:func:`facepuppet.demo.performer.head_pose`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "KEY_NAMES",
    "ARKIT_NAMES",
    "KEY_DESCRIPTIONS",
    "HEAD_AMPLITUDE",
    "Script",
    "performance_script",
    "calibration_script",
    "head_sweep",
]

#: The demo's key expressions, in the order of every weight vector.
KEY_NAMES: tuple[str, ...] = (
    "jawOpen",
    "mouthSmile",
    "mouthFrown",
    "mouthPucker",
    "mouthFunnel",
    "mouthStretch",
    "mouthRollLower",
    "cheekPuff",
    "browInnerUp",
    "browDown",
    "browOuterUp",
    "eyeBlink",
    "eyeWide",
)

#: The ARKit blendshapes each key stands for (both sides of a symmetric pair).
ARKIT_NAMES: dict[str, tuple[str, ...]] = {
    "jawOpen": ("jawOpen",),
    "mouthSmile": ("mouthSmileLeft", "mouthSmileRight"),
    "mouthFrown": ("mouthFrownLeft", "mouthFrownRight"),
    "mouthPucker": ("mouthPucker",),
    "mouthFunnel": ("mouthFunnel",),
    "mouthStretch": ("mouthStretchLeft", "mouthStretchRight"),
    "mouthRollLower": ("mouthRollLower",),
    "cheekPuff": ("cheekPuff",),
    "browInnerUp": ("browInnerUp",),
    "browDown": ("browDownLeft", "browDownRight"),
    "browOuterUp": ("browOuterUpLeft", "browOuterUpRight"),
    "eyeBlink": ("eyeBlinkLeft", "eyeBlinkRight"),
    "eyeWide": ("eyeWideLeft", "eyeWideRight"),
}

#: What the performer does for each key (for prompts during calibration).
KEY_DESCRIPTIONS: dict[str, str] = {
    "jawOpen": "drop the jaw, mouth wide open",
    "mouthSmile": "smile: mouth corners up and out",
    "mouthFrown": "frown: mouth corners down",
    "mouthPucker": "pucker the lips as for a kiss",
    "mouthFunnel": "round the lips into a funnel, as for 'oo'",
    "mouthStretch": "stretch the mouth corners sideways, lips tense",
    "mouthRollLower": "roll the lower lip in over the teeth",
    "cheekPuff": "puff the cheeks with closed lips",
    "browInnerUp": "raise the inner ends of the brows (worry)",
    "browDown": "lower and knit the brows (anger)",
    "browOuterUp": "raise the outer ends of the brows",
    "eyeBlink": "close both eyes",
    "eyeWide": "open the eyes wide",
}

#: Largest head motion of :func:`performance_script`: yaw, pitch, roll (rad), x, y, z (cm).
HEAD_AMPLITUDE: tuple[float, ...] = (0.22, 0.12, 0.08, 1.5, 1.0, 2.0)

#: Secondary keys shown at low weight together with a primary one (natural combinations).
_COMBOS: dict[str, str] = {
    "jawOpen": "browOuterUp",
    "mouthSmile": "eyeBlink",
    "mouthFrown": "browDown",
    "mouthStretch": "browInnerUp",
    "mouthFunnel": "jawOpen",
}

_LEAD_IN = 0.4  # s of neutral face and frontal head at the start
_TAIL = 0.3  # s of neutral face at the end
_MIN_SLOT = 0.3  # s: shortest time given to one key expression
_BLINK = 0.3  # s: duration of a spontaneous blink


@dataclass(frozen=True)
class Script:
    """A scripted performance of the demo's key expressions.

    Attributes
    ----------
    weights : (F, K) float
        Key-expression weights in [0, 1], columns in ``names`` order.
    head_motion : (F, 6) float
        Yaw, pitch, roll (radians) and x, y, z translation (cm) of the head per frame.
    fps : float
        Frames per second.
    names : tuple of K str
        Key names (:data:`KEY_NAMES`).
    marks : dict of str -> int
        For a calibration script, the frame at the middle of each held expression, ``"neutral"`` included;
        empty for a performance.
    holds : dict of str -> (int, int)
        For a calibration script, the frames ``[start, stop)`` over which each expression is held steady.
    spans : dict of str -> (int, int)
        For a calibration script, the frames ``[start, stop)`` of the neutral face with the head moving
        (``"head-motion"``, the marks file's span); empty otherwise.
    """

    weights: np.ndarray
    head_motion: np.ndarray
    fps: float
    names: tuple[str, ...] = KEY_NAMES
    marks: dict[str, int] = field(default_factory=dict)
    holds: dict[str, tuple[int, int]] = field(default_factory=dict)
    spans: dict[str, tuple[int, int]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        w, h = np.shape(self.weights), np.shape(self.head_motion)
        if len(w) != 2 or w[1] != len(self.names):
            raise ValueError(f"weights must have shape (F, {len(self.names)}), got {w}")
        if h != (w[0], 6):
            raise ValueError(f"head_motion must have shape ({w[0]}, 6), got {h}")

    @property
    def n_frames(self) -> int:
        """Number of frames F."""
        return int(self.weights.shape[0])

    @property
    def times(self) -> np.ndarray:
        """(F,) float: the time of each frame in seconds."""
        return np.arange(self.n_frames) / self.fps


def _bump(t: np.ndarray, start: float, rise: float, hold: float, fall: float) -> np.ndarray:
    """A smooth pulse in [0, 1]: raised-cosine rise, flat top, raised-cosine fall (C1 continuous)."""
    out = np.zeros_like(t)
    up = (t >= start) & (t < start + rise)
    out[up] = 0.5 - 0.5 * np.cos(np.pi * (t[up] - start) / rise)
    top = (t >= start + rise) & (t <= start + rise + hold)
    out[top] = 1.0
    t_end = start + rise + hold
    down = (t > t_end) & (t < t_end + fall)
    out[down] = 0.5 + 0.5 * np.cos(np.pi * (t[down] - t_end) / fall)
    return out


def _check_rate(seconds: float, fps: float) -> int:
    if not np.isfinite(fps) or fps <= 0:
        raise ValueError(f"fps must be a positive number, got {fps}")
    if not np.isfinite(seconds) or seconds <= 0:
        raise ValueError(f"seconds must be a positive number, got {seconds}")
    return max(1, int(round(seconds * fps)))


def performance_script(seconds: float = 10.0, fps: float = 30.0, seed: int = 0) -> Script:
    """A scripted performance: every key expression shown clearly once, spontaneous blinks, head motion.

    The keys are shown one after another in a random order, each in its own time slot with a smooth rise,
    a held peak (weight 0.85–1) and a smooth fall that overlaps the next slot; some are joined by a natural
    partner at low weight (a smile narrows the eyes, a frown lowers the brows). Blinks of 0.3 s come every
    2–3.5 s. The head starts frontal and still, then turns and drifts smoothly within
    :data:`HEAD_AMPLITUDE`.

    Parameters
    ----------
    seconds : float
        Length; at least ``0.7 + 13 * 0.3`` = 4.6 s so that every key gets its slot.
    fps : float
        Frames per second.
    seed : int
        Seed of the ``np.random.default_rng`` that picks the order, peaks, blink times and head motion.

    Returns
    -------
    Script
        With ``weights`` (F, 13) and ``head_motion`` (F, 6), F = round(seconds * fps).
    """
    n = _check_rate(seconds, fps)
    k = len(KEY_NAMES)
    min_seconds = _LEAD_IN + _TAIL + k * _MIN_SLOT
    if seconds < min_seconds - 1e-9:
        raise ValueError(f"seconds must be at least {min_seconds:.1f} to show all {k} keys, got {seconds}")
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fps
    weights = np.zeros((n, k))
    index = {name: i for i, name in enumerate(KEY_NAMES)}

    slot = (seconds - _LEAD_IN - _TAIL) / k
    rise = min(0.3, 0.3 * slot)
    order = rng.permutation(k)
    for j, key in enumerate(order):
        start = _LEAD_IN + j * slot
        hold = slot - rise  # the fall of this slot overlaps the rise of the next
        peak = rng.uniform(0.85, 1.0)
        pulse = _bump(t, start, rise, hold, rise)
        col = int(key)
        weights[:, col] = np.maximum(weights[:, col], peak * pulse)
        partner = _COMBOS.get(KEY_NAMES[col])
        if partner is not None:
            pcol = index[partner]
            weights[:, pcol] = np.maximum(weights[:, pcol], rng.uniform(0.25, 0.45) * pulse)

    blink = index["eyeBlink"]
    t_blink = _LEAD_IN + rng.uniform(0.6, 1.5)
    while t_blink + _BLINK < seconds - _TAIL:
        pulse = _bump(t, t_blink, 0.4 * _BLINK, 0.2 * _BLINK, 0.4 * _BLINK)
        weights[:, blink] = np.maximum(weights[:, blink], pulse)
        t_blink += rng.uniform(2.0, 3.5)

    return Script(np.clip(weights, 0.0, 1.0), _head_motion(t, seconds, rng), float(fps))


def _head_motion(t: np.ndarray, seconds: float, rng: np.random.Generator) -> np.ndarray:
    """(F, 6) smooth head motion: two slow sinusoids per channel, eased in from the frontal pose."""
    amp = np.asarray(HEAD_AMPLITUDE)
    freq = rng.uniform(0.08, 0.35, size=(2, 6))
    phase = rng.uniform(0.0, 2.0 * np.pi, size=(2, 6))
    share = np.array([0.6, 0.4])[:, None]
    wave = np.einsum("ac,tac->tc", share, np.sin(2.0 * np.pi * freq[None] * t[:, None, None] + phase[None]))
    ease = _bump(t, _LEAD_IN, min(1.0, 0.2 * seconds), np.inf, 1.0)
    return ease[:, None] * wave * amp[None]


def calibration_script(hold: float = 0.5, transition: float = 0.25, fps: float = 30.0,
                       head_motion: float = 5.0) -> Script:
    """A calibration performance: neutral, then each key expression in turn, held still, then the neutral face
    with the head moving.

    The head is still and frontal while the expressions are shown. The face holds neutral for ``hold``
    seconds, then for each key in :data:`KEY_NAMES` order rises to weight 1 over ``transition`` seconds,
    holds it ``hold`` seconds, and falls back over ``transition`` seconds. Last, for ``head_motion`` seconds,
    the face stays neutral while the head turns, nods, tilts and moves through the whole range of
    :data:`HEAD_AMPLITUDE` (:func:`head_sweep`): what a tracker reports there is no expression.

    Parameters
    ----------
    hold, transition : float
        Seconds of each held expression and of each rise or fall.
    fps : float
        Frames per second.
    head_motion : float
        Seconds of the head-motion span (0: none).

    Returns
    -------
    Script
        ``marks`` gives the middle frame of each hold (``"neutral"`` and every key), ``holds`` its frames,
        ``spans["head-motion"]`` the frames of the head-motion span.
    """
    if not np.isfinite(hold) or hold * fps < 1:
        raise ValueError(f"hold must last at least one frame, got {hold} s at {fps} fps")
    if not np.isfinite(transition) or transition < 0:
        raise ValueError(f"transition must be a non-negative number of seconds, got {transition}")
    if not np.isfinite(head_motion) or head_motion < 0:
        raise ValueError(f"head_motion must be a non-negative number of seconds, got {head_motion}")
    k = len(KEY_NAMES)
    shown = hold + k * (hold + 2.0 * transition)
    seconds = shown + head_motion
    n = _check_rate(seconds, fps)
    t = np.arange(n) / fps
    weights = np.zeros((n, k))
    marks: dict[str, int] = {}
    holds: dict[str, tuple[int, int]] = {}

    def span(t0: float) -> tuple[int, int]:
        a = int(np.ceil(t0 * fps - 1e-9))
        b = int(np.floor((t0 + hold) * fps + 1e-9)) + 1
        return a, min(max(b, a + 1), n)

    holds["neutral"] = span(0.0)
    for i, name in enumerate(KEY_NAMES):
        start = hold + i * (hold + 2.0 * transition)
        if transition > 0:
            weights[:, i] = _bump(t, start, transition, hold, transition)
        else:
            weights[:, i] = ((t >= start) & (t <= start + hold)).astype(float)
        holds[name] = span(start + transition)
    for name, (a, b) in holds.items():
        marks[name] = (a + b - 1) // 2
    motion = np.zeros((n, 6))
    spans: dict[str, tuple[int, int]] = {}
    if head_motion > 0:
        a = int(np.ceil(shown * fps - 1e-9))
        motion[a:] = head_sweep(t[a:] - t[a])
        spans["head-motion"] = (a, n)
    return Script(weights, motion, float(fps), marks=marks, holds=holds, spans=spans)


#: Frequencies (Hz) of :func:`head_sweep`'s channels (yaw, pitch, roll, x, y, z): distinct, so that the
#: channels do not move in lockstep and every combination of directions is visited.
_SWEEP_HZ = (0.45, 0.7, 0.55, 0.3, 0.4, 0.35)
_SWEEP_RISE = 0.5  # s: the sweep eases in from the frontal pose


def head_sweep(t: np.ndarray) -> np.ndarray:
    """(F, 6) head motion through the range of :data:`HEAD_AMPLITUDE`: one sinusoid per channel, each at
    its own frequency (``_SWEEP_HZ``), eased in over half a second from the frontal pose at ``t = 0``."""
    t = np.asarray(t, dtype=float)
    amp = np.asarray(HEAD_AMPLITUDE)
    wave = np.sin(2.0 * np.pi * np.asarray(_SWEEP_HZ)[None] * t[:, None])
    return _bump(t, 0.0, _SWEEP_RISE, np.inf, 1.0)[:, None] * wave * amp[None]
