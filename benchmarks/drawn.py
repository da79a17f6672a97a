"""Things drawn on the face of the shared clips, around MediaPipe's curves of each frame: the robustness copies
``beard`` and ``glasses`` of ``eval_robustness.py`` (and the frames of ``tests/capture/color/test_glasses.py``).

- ``beard``: a dark moustache from under the nose down to the upper lip and a short beard from under the lower
  lip to the chin, of hair strands that move with the face (an older performer's face: dark hair around the
  mouth, where the mouth's rules look for the lips);
- ``glasses``: thick dark rims (a rounded rectangle around each eye, the bridge and the arms) and a bright
  reflection that comes and goes on the lenses and slides across them (:data:`GLARE_PERIOD`): rims near the
  brows and lids, a lens's glare hiding the lid and the eye's white;
- ``sleeve``: a dark sleeve passing down across the upper face now and then (:data:`SLEEVE_PERIOD`), from
  above the brows to under the nose: the eyes hidden, and the sleeve's edges with the eyes' dark over the skin.

Coordinates are image pixels (x right, y down); the curves are (C, 4, 2) in the order of ``CURVE_NAMES``; the
eye-centre distance (``unit``) sizes everything drawn.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: The beard copy's hair: RGB colour, the most it covers (alpha) and the strands' size (eye-centre distances).
HAIR_RGB, HAIR_ALPHA, HAIR_STRAND = (45.0, 34.0, 28.0), 0.92, 0.03
#: A lens: centred this far below the eye centre, with these half-width and half-height (eye-centre distances).
LENS = (0.06, 0.42, 0.27)
#: Rim thickness (eye-centre distances) of thin and thick glasses, and the rims' grey level.
THIN_RIM, THICK_RIM, RIM_GREY = 0.02, 0.065, 28.0
#: The glasses copy's reflection: its strongest cover (share of white), and the period (frames) over which it
#: comes, slides across the lenses and goes (present half of the time).
GLARE, GLARE_PERIOD = 0.6, 150
#: The sleeve copy's sleeve: its RGB colour, half height and half width (eye-centre distances), the frames it
#: takes to pass (from one eye distance above the eyes to 1.5 below them) and the period (frames) it passes in,
#: starting :data:`SLEEVE_PERIOD` / 4 frames into each.
SLEEVE_RGB, SLEEVE_SIZE, SLEEVE_FRAMES, SLEEVE_PERIOD = (60.0, 45.0, 40.0), (0.4, 1.6), 21, 120


def _index() -> dict[str, int]:
    from facepuppet.capture.curves import CURVE_NAMES

    return {n: i for i, n in enumerate(CURVE_NAMES)}


def _eye_frame(curves: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, np.ndarray, np.ndarray]:
    """(right eye centre, left eye centre, their distance, unit vector across (right to left), unit vector down)
    of the curves (C, 4, 2): the eye centres are the upper lids' corners' midpoints."""
    k = _index()
    right, left = (curves[k[n]][[0, 3]].mean(axis=0) for n in ("eye_right_upper", "eye_left_upper"))
    unit = float(np.linalg.norm(left - right))
    across = (left - right) / max(unit, 1e-6)
    return right, left, unit, across, np.array([-across[1], across[0]])


def wear_glasses(rgb: np.ndarray, curves: np.ndarray, rim: float, glare: float = 0.0,
                 glare_at: float = 0.0) -> np.ndarray:
    """The RGB frame (H, W, 3) uint8 with glasses drawn around the eyes of the curves (C, 4, 2): a lens outline
    (a rounded rectangle, :data:`LENS`) per eye, ``rim`` eye-centre distances thick, the bridge between them and
    the arms reaching out to the sides; with ``glare`` > 0 a slanted band of that share of white across each
    lens, moved by ``glare_at`` (-1 to 1) half a lens's width from the lens's middle."""
    import cv2

    right, left, d, across, down = _eye_frame(curves)
    f = 4.0                                 # sub-pixel drawing: coordinates times 4 (thickness in pixels)
    img = rgb.astype(np.float32)
    cover = np.zeros(rgb.shape[:2], np.float32)
    t = max(int(round(rim * d)), 1)
    u = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    # A superellipse (exponent 4): a rounded rectangle.
    sx = np.sign(np.cos(u)) * np.abs(np.cos(u)) ** 0.5
    sy = np.sign(np.sin(u)) * np.abs(np.sin(u)) ** 0.5
    lenses = []
    for side, centre in ((-1, right), (1, left)):
        c = centre + LENS[0] * d * down
        pts = c + (LENS[1] * d * sx)[:, None] * across + (LENS[2] * d * sy)[:, None] * down
        lenses.append(pts)
        cv2.polylines(cover, [np.round(pts * f).astype(np.int32)], True, 1.0, t, cv2.LINE_AA, shift=2)
        outer = c + side * LENS[1] * d * across - 0.1 * d * down
        arm = np.array([outer, outer + side * 0.45 * d * across])
        cv2.polylines(cover, [np.round(arm * f).astype(np.int32)], False, 1.0, t, cv2.LINE_AA, shift=2)
    mid = 0.5 * (right + left)
    bridge = np.array([right + LENS[1] * d * across, mid - 0.04 * d * down, left - LENS[1] * d * across])
    cv2.polylines(cover, [np.round(bridge * f).astype(np.int32)], False, 1.0, t, cv2.LINE_AA, shift=2)
    if glare > 0.0:
        light = np.zeros(rgb.shape[:2], np.float32)
        shift = 0.5 * LENS[1] * d * float(np.clip(glare_at, -1.0, 1.0)) * across
        for pts in lenses:
            c = pts.mean(axis=0) + shift
            band = np.array([c - 0.3 * d * across - 0.2 * d * down, c - 0.1 * d * across - 0.2 * d * down,
                             c + 0.2 * d * across + 0.2 * d * down, c + 0.0 * d * across + 0.2 * d * down])
            cv2.fillPoly(light, [np.round(band * f).astype(np.int32)], float(glare), cv2.LINE_AA, shift=2)
        light = cv2.GaussianBlur(light, (0, 0), 0.03 * d)[..., None]
        img = img * (1.0 - light) + 245.0 * light
    a = np.clip(cover, 0, 1)[..., None]
    img = img * (1.0 - a) + RIM_GREY * a
    return np.clip(img + 0.5, 0, 255).astype(np.uint8)


def _hair_texture(size: int, rng: np.random.Generator) -> np.ndarray:
    """(size, size) float32 in [0, 1]: short dark strands, drawn once in a face space of ``size`` pixels for 2
    eye-centre distances."""
    import cv2

    tex = np.zeros((size, size), np.float32)
    length = HAIR_STRAND * size / 2.0
    for _ in range(size * size // 8):
        x, y = rng.uniform(0, size, 2)
        a = rng.normal(np.pi / 2, 0.35)
        d = length * rng.uniform(0.5, 1.5) * np.array([np.cos(a), np.sin(a)])
        cv2.line(tex, (int(x), int(y)), (int(x + d[0]), int(y + d[1])), float(rng.uniform(0.6, 1.0)), 1, cv2.LINE_AA)
    return np.clip(cv2.GaussianBlur(tex, (0, 0), 0.6) * 1.6, 0.0, 1.0)


def grow_beard(rgb: np.ndarray, curves: np.ndarray, tex: np.ndarray) -> np.ndarray:
    """The RGB frame (H, W, 3) uint8 with a moustache and a short beard drawn around the lips and nostrils of
    the curves (C, 4, 2), of the strands ``tex`` (:func:`_hair_texture`, a face space of its size for 2
    eye-centre distances, eye centres at a quarter and three quarters across, a quarter down)."""
    import cv2

    from facepuppet.capture.curves import bezier_points

    k = _index()
    c = curves
    right, _, unit, across, down = _eye_frame(c)
    upper, lower = bezier_points(c[k["lip_upper_outer"]], 16), bezier_points(c[k["lip_lower_outer"]], 16)
    nose = np.concatenate([bezier_points(c[k["nostril_right"]], 6), bezier_points(c[k["nostril_left"]], 6)])
    corner_r, corner_l = upper[0], upper[-1]
    # Moustache: from just under the nostrils, reaching past the mouth's corners, down to the upper lip.
    top = nose + 0.06 * unit * down
    wing = 0.12 * unit
    moustache = np.concatenate([top, [corner_l + wing * across + 0.1 * unit * down], upper[::-1],
                                [corner_r - wing * across + 0.1 * unit * down]])
    # Beard: from a little under the lower lip to the chin, as wide as the mouth and a little more.
    chin = 0.5 * (corner_r + corner_l) + 1.05 * unit * down
    below = lower + 0.08 * unit * down
    beard = np.concatenate([below, [corner_l + 0.25 * unit * across + 0.5 * unit * down,
                                    chin + 0.45 * unit * across, chin - 0.45 * unit * across,
                                    corner_r - 0.25 * unit * across + 0.5 * unit * down]])
    mask = np.zeros(rgb.shape[:2], np.float32)
    for poly in (moustache, beard):
        cv2.fillPoly(mask, [np.round(poly * 4).astype(np.int32)], 1.0, cv2.LINE_AA, shift=2)
    mask = cv2.GaussianBlur(mask, (0, 0), 0.08 * unit)
    size = tex.shape[0]
    turn = np.array([[across[0], -across[1]], [across[1], across[0]]]) * unit / (size / 2.0)
    S = np.column_stack([turn, right - turn @ [size / 4.0, size / 4.0]])
    strands = cv2.warpAffine(tex, S, rgb.shape[1::-1], flags=cv2.INTER_LINEAR)
    a = (HAIR_ALPHA * mask * (0.55 + 0.45 * strands))[..., None]
    hair = np.array(HAIR_RGB, np.float32)
    return np.clip(a * hair + (1.0 - a) * rgb.astype(np.float32), 0, 255).astype(np.uint8)


def _faces(src: Path, model: str):
    """(frame index, RGB frame, MediaPipe's (``model``) curves or None) of each frame of the video ``src``."""
    from facepuppet.capture.tracking import make_tracker
    from facepuppet.io.frames import open_media

    mp = make_tracker("mediapipe", model_path=model, running_mode="video")
    try:
        with open_media(src) as frames:
            for i, rgb in enumerate(frames):
                f = mp.track(rgb, int(round(i * 1000 / frames.fps)))
                yield i, rgb, (f.curves if f.valid else None)
    finally:
        mp.close()


def bearded(src: Path, model: str):
    """The frames (RGB uint8) of the ``beard`` copy of the video ``src`` (:func:`grow_beard` on MediaPipe's
    curves of each frame); a frame without a face is left as it is."""
    tex = _hair_texture(400, np.random.default_rng(0))
    for _, rgb, curves in _faces(src, model):
        yield rgb if curves is None else grow_beard(rgb, curves, tex)


def spectacled(src: Path, model: str):
    """The frames (RGB uint8) of the ``glasses`` copy of the video ``src``: thick rims on MediaPipe's curves of
    each frame, and a reflection of up to :data:`GLARE` that rises and falls over the first half of every
    :data:`GLARE_PERIOD` frames while sliding across the lenses; a frame without a face is left as it is."""
    for i, rgb, curves in _faces(src, model):
        yield rgb if curves is None else glasses_copy_frame(rgb, curves, i)


def glasses_copy_frame(rgb: np.ndarray, curves: np.ndarray, i: int) -> np.ndarray:
    """Frame ``i`` of the ``glasses`` copy: thick rims on the curves (C, 4, 2) and the reflection of that frame
    (:func:`spectacled`'s schedule)."""
    phase = (i % GLARE_PERIOD) / GLARE_PERIOD
    glare = GLARE * max(np.sin(2.0 * np.pi * phase), 0.0)
    return wear_glasses(rgb, curves, THICK_RIM, glare, 4.0 * phase - 1.0)


def pass_sleeve(rgb: np.ndarray, curves: np.ndarray, t: float) -> np.ndarray:
    """The RGB frame with the sleeve (:data:`SLEEVE_RGB`, :data:`SLEEVE_SIZE`) across the face of the curves
    (C, 4, 2), ``t`` (0 to 1) of its way down: its middle from one eye distance above the eyes' midpoint to 1.5
    under it, along the face's down direction, level with the eyes' line."""
    import cv2

    right, left, d, across, down = _eye_frame(curves)
    middle = 0.5 * (right + left) + d * (-1.0 + 2.5 * t) * down
    half_h, half_w = SLEEVE_SIZE
    corners = np.array([middle + d * (sx * half_w * across + sy * half_h * down)
                        for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
    out = rgb.copy()
    cv2.fillConvexPoly(out, np.round(corners * 4).astype(np.int32), SLEEVE_RGB, lineType=cv2.LINE_AA, shift=2)
    return out


def sleeved(src: Path, model: str):
    """The frames (RGB uint8) of the ``sleeve`` copy of the video ``src``: the sleeve passes down across the face
    over :data:`SLEEVE_FRAMES` frames, a quarter into every :data:`SLEEVE_PERIOD` frames, on MediaPipe's curves
    of each frame; a frame without a face is left as it is."""
    for i, rgb, curves in _faces(src, model):
        k = i % SLEEVE_PERIOD - SLEEVE_PERIOD // 4
        passing = curves is not None and 0 <= k < SLEEVE_FRAMES
        yield pass_sleeve(rgb, curves, k / (SLEEVE_FRAMES - 1)) if passing else rgb


#: The drawn copies: name -> frames of the copy of a video, given MediaPipe's model file.
DRAWN = {"beard": bearded, "glasses": spectacled, "sleeve": sleeved}
