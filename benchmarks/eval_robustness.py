"""The colour tracker on altered copies of the shared clips: dim, warm, noisy and small faces.

The tracker should hold up on footage unlike the three shared clips (dim light, small faces, ...). This makes
such footage from the shared clips and measures it with the shared yardstick:

- ``dim``: every channel times 0.35 (an underexposed room);
- ``warm``: red times 1.3, green 0.95, blue 0.65 (tungsten light on an uncorrected camera);
- ``noisy``: Gaussian noise of standard deviation 12 grey levels per channel (a cheap sensor in low light);
- ``small``: the frame shrunk to 2/5 and set on a grey (90) frame of the original size (a face far away);
- ``face80``: the frame shrunk so that the face is 80 px wide (:data:`FACE_WIDTH` eye-centre distances, the
  distance MediaPipe finds on the clip's first frames) and set on a grey frame the same way;
- ``cool``: red times 0.8, blue 1.25 (a monitor's or daylight's blue cast);
- ``rolled``: the frame turned 15 degrees counter-clockwise about its centre, edges reflected (a tilted head);
- ``mirrored``: left and right swapped (a webcam's mirrored view);
- ``portrait``: the middle 9:16 of the frame's width kept (a phone held upright);
- ``darker``: skin-coloured pixels (a window of Cr and Cb around skin's) darkened by a gamma of 1.6 and made
  browner (R 0.72, G 0.62, B 0.55), feathered over 3 px (a darker complexion, roughly: the lips and the warm
  background within the window darken too);
- ``deep``: the same skin-coloured pixels scaled channel by channel by R 0.42, G 0.39, B 0.35 (a deep
  complexion: cheeks of about (200, 160, 140) become (84, 62, 49); linear, so the features keep their contrast
  to the skin as a ratio, and the eyes' white, the hair and a lighter wall behind keep theirs);
- ``lowres``: the frame shrunk to 2/5 and saved as JPEG of quality 35, kept at that size (a cheap webcam's stream);
- ``backlit``: the frame halved in brightness under a veiling glare that falls from white at the top to nothing
  two thirds down (a bright window behind and above the performer: low contrast on the upper face);
- ``haze``: the contrast times 0.55 under an even veil of 100 levels (haze, or a bright scene scattered in the lens).
- ``long`` and ``short``: the frame stretched to 1.2 and squashed to 0.85 of its height (the middle kept, or the
  edges reflected): faces whose mouth and chin sit farther from or nearer to the eyes;
- ``grey``: the frame's luma in all three channels (a monochrome or infrared camera, black-and-white footage: no
  skin colour anywhere);
- ``hd``: the frame enlarged to 1080 rows and set in the middle of a 1920 x 1080 frame, the sides reflected (a
  1080p webcam or phone close to the face: a face about 2.25 times as many pixels wide);
- ``sidelit``: the light falling from the frame's left to 0.3 of it on the right through a soft logistic step at
  the frame's middle, 0.06 of the width (a window beside the performer: one half of the face in shade);
- ``toplit``: the light falling linearly from the frame's top row to 0.4 of it at the bottom row (a lamp above
  the performer);
- ``lamp_left`` and ``lamp_right``: a warm lamp's light (R, G, B times 1.15, 1.0, 0.75) on the frame's left
  (right) half and a cool, dimmer window's light (0.6, 0.7, 0.85) on the other, through the same soft step as
  ``sidelit``'s (two lights of different colours on the two halves of the face).

Background copies: the face (an oval around MediaPipe's eyes on the original frame, feathered) cut out and set on
a made-up scene, the kind of room that fools a skin-colour model:

- ``wood``: warm wooden boards;
- ``beige``: a beige wall under a warm light falling off from the left;
- ``skin_object``: wood with a face-sized object of the performer's own skin colour beside the face;
- ``poster``: wood with a drawn face (skin oval, dark eyes and brows, nostrils, mouth) beside the face;
- ``stage_hand``: a dark stage with props, the frame shrunk to 0.42 (a face about 90-115 px wide), a hand of the
  performer's skin colour passing over the lower face twice.

Drawn on the face (around MediaPipe's curves of each frame; ``drawn.py``):

- ``beard``: a dark moustache and a short beard of hair strands that move with the face;
- ``glasses``: thick dark rims, the bridge and the arms, and a bright reflection that comes and goes on the
  lenses, sliding across them;
- ``sleeve``: a dark sleeve passing down across the upper face in 21 frames of every 120 (0.7 s every 4 s at 30
  frames a second: something passing in front of the face; the eyes hidden, the face lost and found again).

Re-posed (``turned.py``): ``turned``, the face turning (yaw) and nodding (pitch) by a sweep of up to
:data:`TURNED` degrees either way, its mesh of MediaPipe's 3-D landmarks rotated and warped, hair and background
kept.

Two or more conditions at once (ordinary footage rarely has one thing wrong): a variant may be a chain of names
joined by ``+``, applied in order to each frame: the first may be any copy above, the rest are the per-frame
ones (``dim`` ... ``lamp_right``). ``wood+warm`` is the face before wood with face and wall in one warm light,
``dim+noisy`` a dark room's noisy sensor. ``--compounds`` measures the chains of :data:`COMPOUNDS` instead of
the variants.

Each copy is written as MPEG-4 into a temporary folder, tracked with ``--backend color`` and the built-in
profile (no landmark model: the copies test the colour pipeline alone), and scored by
``../shared/eval/track_agreement.py`` (mean NME against MediaPipe on the same frames, jitter ratio, coverage).
The bars of the shared clips are NME <= 0.05, jitter ratio <= 1.5, coverage >= 0.98.

Run: ``python benchmarks/eval_robustness.py [--clips performer_a performer_c] [--variants dim warm noisy small
face80 cool rolled mirrored portrait darker deep lowres backlit haze long short grey hd sidelit toplit lamp_left
lamp_right wood beige skin_object poster stage_hand beard glasses sleeve turned | --compounds] [--assets PATH]
[--jobs 2]``
(about 20 s per copy of a or c on one core, MediaPipe's reference included; ``performer_b_exaggerated`` is
three times as long).
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import drawn  # noqa: E402  (this folder's module of things drawn on the face)
import turned  # noqa: E402  (this folder's module of faces re-posed)

ROOT = Path(__file__).resolve().parents[1]
VARIANTS = ("dim", "warm", "noisy", "small", "face80", "cool", "rolled", "mirrored", "portrait", "darker", "deep",
            "lowres", "backlit", "haze", "long", "short", "grey", "hd", "sidelit", "toplit", "lamp_left", "lamp_right")
BACKGROUNDS = ("wood", "beige", "skin_object", "poster", "stage_hand")
DRAWN = tuple(drawn.DRAWN)
REPOSED = ("turned",)
#: The ``turned`` copy's largest yaw and pitch put in either way, degrees (:func:`turned.sweep`; MediaPipe reads
#: about 0.6 of them: about 18 and 9 degrees).
TURNED = (30.0, 15.0)
#: Chains of two or three conditions (``--compounds``): a webcam's noisy, JPEG-coded stream in a dark, warm or cool
#: room, a phone's HD stream in a dark room, a wall of the face's colour in the same warm light, glasses on a small
#: or deep-skinned face, and so on.
COMPOUNDS = ("dim+noisy", "warm+noisy+lowres", "small+noisy", "wood+warm", "glasses+lowres", "beard+dim",
             "cool+face80", "sidelit+noisy", "grey+small", "backlit+lowres", "glasses+deep", "beige+dim+noisy",
             "hd+dim+noisy")
#: The face cut out: an oval centred this far below the eyes, with these half-axes (eye-centre distances).
FACE_OVAL = (0.8, 1.2, 1.75)
STAGE_SCALE = 0.42          # the stage copy's frame scale (a face about 90-115 px wide)
#: A face's width in eye-centre distances (bizygomatic breadth over the distance of the pupils, adults).
FACE_WIDTH = 2.2
#: The face80 copy's face width, pixels.
SMALL_FACE = 80.0
ROLL = 15.0                 # the rolled copy's turn, degrees counter-clockwise
#: The darker copy: the skin window's centre and half-width in Cr and Cb (OpenCV's YCrCb, 0-255), the feather
#: of its edge (levels), the gamma and the RGB gains applied inside it.
SKIN_CR, SKIN_CB, SKIN_HALF, SKIN_FEATHER = 150.0, 110.0, 15.0, 10.0
DARKER_GAMMA, DARKER_GAINS = 1.6, (0.72, 0.62, 0.55)
DEEP_GAINS = (0.42, 0.39, 0.35)     # the deep copy's RGB gains inside the skin window
LOWRES_QUALITY = 35         # JPEG quality of the lowres copy's frames
#: Vertical scale of the ``long`` and ``short`` copies (faces whose mouth and chin sit farther from or nearer to
#: the eyes: people's proportions differ that much, the eye-mouth distance from about 1 to 1.5 eye distances).
LONG, SHORT = 1.2, 0.85
#: The ``hd`` copy's frame (width, height), pixels.
HD = (1920, 1080)
#: The ``sidelit`` copy: the light left on the frame's right side (a share of the left side's) and the width of
#: the soft step between them at the frame's middle (a share of the frame's width).
SIDE_FLOOR, SIDE_SOFT = 0.3, 0.06
#: The ``toplit`` copy: the light left at the frame's bottom row (a share of the top row's).
TOP_FLOOR = 0.4
#: The ``lamp_left`` and ``lamp_right`` copies: the warm lamp's and the cool window's gains of R, G, B.
LAMP, WINDOW = (1.15, 1.0, 0.75), (0.6, 0.7, 0.85)


def _shrunk(rgb: np.ndarray, f: float) -> np.ndarray:
    """The frame shrunk by ``f`` and set on a grey (90) frame of the original size, a third down, a quarter in."""
    import cv2

    h, w = rgb.shape[:2]
    s = cv2.resize(rgb, (max(round(w * f), 1), max(round(h * f), 1)), interpolation=cv2.INTER_AREA)
    out = np.full_like(rgb, 90)
    out[h // 3:h // 3 + s.shape[0], w // 4:w // 4 + s.shape[1]] = s[:h - h // 3, :w - w // 4]
    return out


def face_unit(src: Path, model: Path, frames: int = 10) -> float:
    """The median eye-centre distance (pixels) MediaPipe (model file ``model``) finds on the first ``frames`` of
    ``src``."""
    import cv2

    from facepuppet.capture.color.eye_anchors import eye_centres_of
    from facepuppet.capture.tracking import make_tracker

    cap = cv2.VideoCapture(str(src))
    tracker, units = make_tracker("mediapipe", model_path=model, running_mode="image"), []
    for i in range(frames):
        ok, bgr = cap.read()
        if not ok:
            break
        f = tracker.track(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), 33 * i)
        if f.valid:
            right, left = eye_centres_of(f.curves)
            units.append(float(np.hypot(*(left - right))))
    cap.release()
    tracker.close()
    if not units:
        raise RuntimeError(f"{src}: no face in the first {frames} frames")
    return float(np.median(units))


def altered(rgb: np.ndarray, variant: str, rng: np.random.Generator, unit: float | None = None) -> np.ndarray:
    """One RGB frame (H, W, 3) uint8 as the ``variant`` copy shows it (module docstring); ``unit``: the clip's
    eye-centre distance in pixels (``face80`` only)."""
    import cv2

    x = rgb.astype(np.float32)
    if variant == "dim":
        x = x * 0.35
    elif variant == "warm":
        x = x * np.array([1.3, 0.95, 0.65], dtype=np.float32)
    elif variant == "noisy":
        x = x + rng.normal(0.0, 12.0, x.shape).astype(np.float32)
    elif variant == "small":
        h, w = rgb.shape[:2]
        s = cv2.resize(rgb, (w * 2 // 5, h * 2 // 5), interpolation=cv2.INTER_AREA)
        out = np.full_like(rgb, 90)
        out[h // 3:h // 3 + s.shape[0], w // 4:w // 4 + s.shape[1]] = s
        return out
    elif variant == "face80":
        if unit is None:
            raise ValueError("the face80 copy needs the clip's eye-centre distance (unit)")
        return _shrunk(rgb, min(SMALL_FACE / (FACE_WIDTH * unit), 1.0))
    elif variant == "cool":
        x = x * np.array([0.8, 1.0, 1.25], dtype=np.float32)
    elif variant == "rolled":
        h, w = rgb.shape[:2]
        turn = cv2.getRotationMatrix2D((w / 2.0, h / 2.0), ROLL, 1.0)
        return cv2.warpAffine(rgb, turn, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    elif variant == "mirrored":
        return np.ascontiguousarray(rgb[:, ::-1])
    elif variant == "portrait":
        h, w = rgb.shape[:2]
        keep = min(w, int(h * 9 / 16) // 2 * 2)
        return np.ascontiguousarray(rgb[:, (w - keep) // 2:(w - keep) // 2 + keep])
    elif variant in ("darker", "deep"):
        ycc = cv2.cvtColor(rgb, cv2.COLOR_RGB2YCrCb).astype(np.float32)

        def window(v, centre):
            return np.clip(1.0 - np.maximum(np.abs(v - centre) - SKIN_HALF, 0.0) / SKIN_FEATHER, 0.0, 1.0)

        m = cv2.GaussianBlur(window(ycc[..., 1], SKIN_CR) * window(ycc[..., 2], SKIN_CB), (0, 0), 3.0)[..., None]
        u = x / 255.0
        if variant == "darker":
            dark = u ** DARKER_GAMMA * np.array(DARKER_GAINS, dtype=np.float32)
        else:
            dark = u * np.array(DEEP_GAINS, dtype=np.float32)
        x = 255.0 * (m * dark + (1.0 - m) * u)
    elif variant == "lowres":
        h, w = rgb.shape[:2]
        s = cv2.resize(rgb, (w * 2 // 5, h * 2 // 5), interpolation=cv2.INTER_AREA)
        # JPEG codes luma and subsampled chroma of BGR images (a camera's JPEG: RGB taken as BGR would code
        # the wrong luma).
        ok, jpeg = cv2.imencode(".jpg", cv2.cvtColor(s, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, LOWRES_QUALITY])
        return cv2.cvtColor(cv2.imdecode(jpeg, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    elif variant == "backlit":
        glare = np.clip(np.linspace(1.0, 0.0, rgb.shape[0], dtype=np.float32) * 1.4 - 0.5, 0.0, 1.0)
        x = x * 0.5 + 255.0 * glare[:, None, None]
    elif variant == "haze":
        x = x * 0.55 + 100.0
    elif variant in ("long", "short"):
        h, w = rgb.shape[:2]
        s = LONG if variant == "long" else SHORT
        tall = cv2.resize(rgb, (w, int(round(h * s))), interpolation=cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR)
        top = (tall.shape[0] - h) // 2
        if top >= 0:
            return np.ascontiguousarray(tall[top:top + h])
        return cv2.copyMakeBorder(tall, -top, h - tall.shape[0] + top, 0, 0, cv2.BORDER_REFLECT)
    elif variant == "grey":
        return np.repeat(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)[..., None], 3, axis=2)
    elif variant == "sidelit":
        columns = np.arange(rgb.shape[1], dtype=np.float32) / rgb.shape[1]
        light = SIDE_FLOOR + (1.0 - SIDE_FLOOR) / (1.0 + np.exp((columns - 0.5) / SIDE_SOFT))
        x = x * light[None, :, None]
    elif variant == "toplit":
        x = x * np.linspace(1.0, TOP_FLOOR, rgb.shape[0], dtype=np.float32)[:, None, None]
    elif variant in ("lamp_left", "lamp_right"):
        columns = np.arange(rgb.shape[1], dtype=np.float32) / rgb.shape[1]
        side = 1.0 / (1.0 + np.exp((columns - 0.5) / SIDE_SOFT * (1.0 if variant == "lamp_left" else -1.0)))
        x = x * (side[:, None] * np.float32(LAMP) + (1.0 - side[:, None]) * np.float32(WINDOW))[None]
    elif variant == "hd":
        h, w = rgb.shape[:2]
        big = cv2.resize(rgb, (int(round(w * HD[1] / h)), HD[1]), interpolation=cv2.INTER_CUBIC)
        side = HD[0] - big.shape[1]
        if side < 0:                                    # wider than 16:9: the middle kept
            return np.ascontiguousarray(big[:, -side // 2:-side // 2 + HD[0]])
        return cv2.copyMakeBorder(big, 0, 0, side // 2, side - side // 2, cv2.BORDER_REFLECT)
    else:
        raise ValueError(f"unknown variant {variant!r}; choose from {', '.join(VARIANTS)}")
    return np.clip(x + 0.5, 0, 255).astype(np.uint8)


def _scene(variant: str, shape: tuple[int, ...], skin: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """(H, W, 3) float32 RGB scene of a background copy."""
    import cv2

    h, w = shape[:2]
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    grain = np.sin(x / 7.0 + 3.0 * np.sin(y / 40.0)) + 0.5 * np.sin(x / 2.3 + y / 90.0)
    img = np.ascontiguousarray(np.array([196.0, 140.0, 96.0])[None, None] * (1.0 + 0.12 * grain[..., None]),
                               dtype=np.float32)
    sk = tuple(float(v) for v in skin)
    d = 0.2 * w                                   # eye distance of the object or poster beside the face
    if variant == "beige":
        ramp = (1.25 - 0.55 * x / w)[..., None] * (1.0 - 0.15 * y / h)[..., None]
        img = np.array([214.0, 188.0, 160.0])[None, None] * ramp * np.array([1.0, 0.93, 0.8])
    elif variant == "skin_object":
        cv2.ellipse(img, ((0.1 * w, 0.55 * h), (2.4 * d, 3.4 * d), 10.0), sk, -1)
    elif variant == "poster":
        cx, cy, dark = 0.1 * w, 0.4 * h, tuple(float(v) for v in 0.3 * skin)
        cv2.ellipse(img, ((cx, cy + 0.8 * d), (2.4 * d, 3.5 * d), 0.0), sk, -1)
        for s in (-1, 1):
            cv2.ellipse(img, ((cx + 0.5 * s * d, cy), (0.45 * d, 0.2 * d), 0.0), dark, -1)
            cv2.ellipse(img, ((cx + 0.5 * s * d, cy - 0.35 * d), (0.6 * d, 0.12 * d), 0.0), dark, -1)
        cv2.ellipse(img, ((cx, cy + 1.15 * d), (0.8 * d, 0.15 * d), 0.0), tuple(float(v) for v in 0.5 * skin), -1)
    elif variant == "stage_hand":
        img = np.full((h, w, 3), 28.0, np.float32) * (0.8 + 0.4 * y[..., None] / h)
        for _ in range(14):
            x0, y0 = int(rng.integers(0, w - 40)), int(rng.integers(0, h - 40))
            cv2.rectangle(img, (x0, y0), (x0 + int(rng.integers(20, 160)), y0 + int(rng.integers(10, 120))),
                          tuple(float(v) for v in rng.uniform(15, 110, 3)), -1)
    return np.clip(img + rng.normal(0.0, 3.0, img.shape), 0, 255).astype(np.float32)


def _oval(eyes: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """(H, W) float32 feathered face oval of :data:`FACE_OVAL` around the eye centres (2, 2) (right, left)."""
    import cv2

    right, left = eyes
    d = float(np.linalg.norm(left - right))
    across = (left - right) / max(d, 1e-6)
    centre = 0.5 * (left + right) + FACE_OVAL[0] * d * np.array([-across[1], across[0]])
    m = np.zeros(shape[:2], np.float32)
    cv2.ellipse(m, (tuple(map(float, centre)), (2 * FACE_OVAL[1] * d, 2 * FACE_OVAL[2] * d),
                    float(np.degrees(np.arctan2(across[1], across[0])))), 1.0, -1)
    return cv2.GaussianBlur(m, (0, 0), 3.0)


def _hand(shape: tuple[int, ...], centre: np.ndarray, size: float) -> np.ndarray:
    """(H, W) float32 mask of a hand (palm, four fingers, thumb) of palm width ``size``, tilted 20 degrees."""
    import cv2

    m = np.zeros(shape[:2], np.float32)
    a = np.radians(-20.0)
    at = lambda u, v: (float(centre[0] + size * (np.cos(a) * u - np.sin(a) * v)),  # noqa: E731
                       float(centre[1] + size * (np.sin(a) * u + np.cos(a) * v)))
    cv2.ellipse(m, (at(0, 0), (size, 1.15 * size), -20.0), 1.0, -1)
    for u, length in zip((-0.33, -0.11, 0.11, 0.33), (0.75, 0.9, 0.85, 0.65), strict=True):
        cv2.ellipse(m, (at(u, -0.5 - length / 2), (0.2 * size, length * size), -20.0), 1.0, -1)
    cv2.ellipse(m, (at(0.6, -0.05), (0.22 * size, 0.6 * size), -70.0), 1.0, -1)
    return cv2.GaussianBlur(m, (0, 0), 1.5)


def composited(src: Path, variant: str, model: str):
    """The frames (RGB uint8) of a background copy of the video ``src``: the face cut out around MediaPipe's
    eyes (``model``) and set on the variant's scene; a frame without a face keeps the last face's oval."""
    import cv2

    from facepuppet.capture.curves import CURVE_NAMES
    from facepuppet.capture.tracking import make_tracker
    from facepuppet.io.frames import open_media

    k = {n: i for i, n in enumerate(CURVE_NAMES)}
    eye_r, eye_rl, eye_l, lip = k["eye_right_upper"], k["eye_right_lower"], k["eye_left_upper"], k["lip_upper_outer"]
    mp = make_tracker("mediapipe", model_path=model, running_mode="video")
    rng = np.random.default_rng(0)
    back, eyes, skin, mouth = None, None, None, None
    try:
        with open_media(src) as frames:
            for i, rgb in enumerate(frames):
                f = mp.track(rgb, int(round(i * 1000 / frames.fps)))
                if f.valid:
                    c = f.curves
                    eyes = np.stack([c[j][[0, 3]].mean(axis=0) for j in (eye_r, eye_l)])
                    mouth = c[lip].mean(axis=0)
                    if skin is None:                                                # a cheek below the right eye
                        p = np.round(0.5 * (c[eye_rl, 1] + c[lip, 0])).astype(int)
                        skin = rgb[p[1] - 4:p[1] + 4, p[0] - 4:p[0] + 4].reshape(-1, 3).mean(axis=0)
                if eyes is None:
                    continue
                img, e, mo = rgb.astype(np.float32), eyes, mouth
                if variant == "stage_hand":
                    h, w = rgb.shape[:2]
                    M = np.array([[STAGE_SCALE, 0.0, 0.35 * w], [0.0, STAGE_SCALE, 0.25 * h]])
                    img = cv2.warpAffine(rgb, M, (w, h), flags=cv2.INTER_AREA).astype(np.float32)
                    e, mo = eyes * STAGE_SCALE + M[:, 2], mouth * STAGE_SCALE + M[:, 2]
                if back is None:
                    back = _scene(variant, rgb.shape, skin, rng)
                m = _oval(e, rgb.shape)[..., None]
                out = m * img + (1.0 - m) * back
                t = (i % 90) / 89.0
                if variant == "stage_hand" and 0.3 < t < 0.7:              # the hand passes, 36 of every 90 frames
                    unit = float(np.linalg.norm(e[1] - e[0]))
                    q = np.sin(np.pi * (t - 0.3) / 0.4)
                    hand = _hand(rgb.shape, mo + [unit * (2.6 - 4.4 * q), 0.5 * unit], 1.8 * unit)[..., None]
                    out = hand * skin + (1.0 - hand) * out
                yield np.clip(out, 0, 255).astype(np.uint8)
    finally:
        mp.close()


def write_copy(src: Path, variant: str, out: Path, model: str | None = None) -> None:
    """Write the ``variant`` copy of the video ``src`` to ``out`` (MPEG-4, same rate, same size but for
    ``lowres``; a chain ``a+b+...`` applies its copies in order); the background, drawn and turned copies and
    ``face80`` need MediaPipe's ``model`` file."""
    import cv2

    first, *rest = variant.split("+")
    cap = cv2.VideoCapture(str(src))
    fps = cap.get(cv2.CAP_PROP_FPS) or 30.0
    rng = np.random.default_rng(0)
    writer = None
    scenes = composited(src, first, model) if first in BACKGROUNDS else (
        drawn.DRAWN[first](src, model) if first in DRAWN else (
            (rgb for rgb, _ in turned.turned_frames(src, model, *TURNED)) if first in REPOSED else None))
    alter = rest if scenes is not None else [first, *rest]
    unit = face_unit(src, model) if "face80" in alter else None
    while True:
        ok, bgr = cap.read()
        if not ok:
            break
        if scenes is not None:
            rgb = next(scenes, None)
            if rgb is None:
                break
        else:
            rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
        for step in alter:
            rgb = altered(rgb, step, rng, unit)
        if writer is None:
            writer = cv2.VideoWriter(str(out), cv2.VideoWriter_fourcc(*"mp4v"), fps, rgb.shape[1::-1])
        writer.write(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    cap.release()
    if writer is None:
        raise RuntimeError(f"{src}: no frames")
    writer.release()


def measure(job: tuple[str, str, str, str]) -> tuple[str, str, str]:
    """Make, track and score one copy; returns (clip, variant, the yardstick's summary line)."""
    clip, variant, assets, tmp = job
    os.environ.pop("FACEPUPPET_FACE_LANDMARKER", None)
    from facepuppet.capture.color.tracker import ColorTracker
    from facepuppet.capture.tracking import track_media
    from facepuppet.errors import FacepuppetError
    from facepuppet.io.track import save_track

    video = Path(tmp) / f"{clip}_{variant}.mp4"
    write_copy(Path(assets) / "video" / f"{clip}.mp4", variant, video,
               model=str(Path(assets) / "models" / "face_landmarker.task"))
    track = Path(tmp) / f"{clip}_{variant}.npz"
    try:
        save_track(track, track_media(video, ColorTracker(), progress=False))
    except FacepuppetError as e:            # no face in any frame: a copy the tracker fails whole
        return clip, variant, f"tracking failed: {e}"
    env = dict(os.environ, FACEPUPPET_FACE_LANDMARKER=str(Path(assets) / "models" / "face_landmarker.task"))
    done = subprocess.run([sys.executable, str(ROOT.parent / "shared" / "eval" / "track_agreement.py"),
                           str(video), str(track)], capture_output=True, text=True, env=env)
    lines = [line for line in done.stdout.splitlines() if line.startswith("mean NME")]
    return clip, variant, lines[0] if lines else f"yardstick failed: {done.stderr.strip()[-200:]}"


def variant_name(text: str) -> str:
    """``text`` if it names a copy or a chain of them (``a+b+...``: any copy first, then per-frame ones); else
    :class:`argparse.ArgumentTypeError`."""
    parts = text.split("+")
    for i, part in enumerate(parts):
        known = VARIANTS + BACKGROUNDS + DRAWN + REPOSED if i == 0 else VARIANTS
        if part not in known:
            where = "" if len(parts) == 1 else f" (part {i + 1} of {text!r}: after the first, only per-frame copies)"
            raise argparse.ArgumentTypeError(f"unknown copy {part!r}{where}; choose from {', '.join(known)}")
    return text


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clips", nargs="+", default=["performer_a", "performer_c"])
    ap.add_argument("--variants", nargs="+", type=variant_name, default=list(VARIANTS + BACKGROUNDS + DRAWN + REPOSED),
                    help="copies, or chains of them joined by '+' (default: every single copy)")
    ap.add_argument("--compounds", action="store_true", help=f"measure the chains {' '.join(COMPOUNDS)} instead")
    ap.add_argument("--assets", default=str(ROOT.parent / "shared" / "assets"))
    ap.add_argument("--jobs", type=int, default=2, help="copies measured at once (processes)")
    args = ap.parse_args(argv)
    for clip in args.clips:
        if not (Path(args.assets) / "video" / f"{clip}.mp4").is_file():
            ap.error(f"--clips: {Path(args.assets) / 'video' / (clip + '.mp4')} does not exist")

    print(f"{'copy':24s} {'NME':>7s} {'jitter':>7s} {'coverage':>9s}")
    with tempfile.TemporaryDirectory(prefix="facepuppet-robust-") as tmp, \
            ProcessPoolExecutor(max(1, args.jobs)) as pool:
        variants = COMPOUNDS if args.compounds else args.variants
        jobs = [(c, v, args.assets, tmp) for c in args.clips for v in variants]
        for clip, variant, line in pool.map(measure, jobs):
            m = re.search(r"MediaPipe ([\d.nan]+); jitter ratio ([\d.nan]+); coverage ([\d.]+)", line)
            if m:
                print(f"{clip + '_' + variant:24s} {m[1]:>7s} {m[2]:>7s} {m[3]:>9s}", flush=True)
            else:
                print(f"{clip + '_' + variant:24s} {line}", flush=True)
    print("bars (shared clips): NME <= 0.05, jitter ratio <= 1.5, coverage >= 0.98")
    return 0


if __name__ == "__main__":
    sys.exit(main())
