"""The colour tracker in front of skin-coloured and cluttered scenes, all made here from the shared clips.

- performer_c composited onto warm wood, a wall of the performer's own skin colour, a blotchy warm texture, a
  beige wall under a warm light gradient, wood with a face-sized skin-coloured object beside the face, and wood
  with a drawn face (a poster: skin oval, dark eyes, brows, nostrils and mouth) beside it: the face is found and
  followed (curves near MediaPipe's on the original frames) and no frame is tracked on the background;
- performer_a small (a face about 100 px wide) on a dark, cluttered stage, a skin-coloured hand (palm and
  fingers in the performer's skin colour) passing over the lower face: frames where the face is mostly seen are
  tracked near MediaPipe's curves, frames where it is mostly covered are not valid or still on the face, never on
  the hand, and the face is tracked again once the hand has gone;
- performer_b on wood, and on wood beside a drawn face: a frame mostly of bright boards, whose equalised grey
  levels flatten the face for the face cascade;
- performer_c and performer_b before wood, face and wall in one warm light (the face as orange as the boards);
- performer_c and performer_b filmed in grey (a monochrome camera: no skin colour anywhere) are found and
  followed, and grey scenes without a face give no face;
- performer_c and performer_b given a deep complexion (their skin's pixels darkened to a deep brown) are found
  at about their size and followed;
- performer_c, performer_a and performer_b lit from one side (one half of the face in shade), by two lights of
  different colours (a warm lamp on one side, a cool window's light on the other) and from above are followed at
  their size.
"""

import cv2
import numpy as np
import pytest
from composites import IDX, background, curve_nme, eye_centres, eye_distance, face_mask, followed, performer_clip

from facepuppet.capture.color.detect import face_windows
from facepuppet.capture.color.tracker import ColorTracker
from facepuppet.capture.curves import bezier_points

#: Width of the canvas of the wide scenes (the clip's frames sit in its middle), pixels.
WIDE = 720
#: The stage: its size (w, h), the performer's scale on it and where the frame's corner goes.
STAGE = ((640, 480), 0.3, (250, 120))
#: A warm light's gains of R, G, B (a tungsten lamp before a camera balanced for daylight).
WARM = (1.3, 0.95, 0.65)
#: Farthest a tracked eye centre may lie from the reference's while the hand passes, eye-centre distances.
EYES_OFF = 0.35


@pytest.fixture(scope="module")
def performer(assets, face_landmarker):
    return performer_clip(assets, face_landmarker, "performer_c")


@pytest.fixture(scope="module")
def performer_a(assets, face_landmarker):
    return performer_clip(assets, face_landmarker, "performer_a")


@pytest.fixture(scope="module")
def performer_b(assets, face_landmarker):
    return performer_clip(assets, face_landmarker, "performer_b_exaggerated")


def _inside(point, mask):
    x, y = np.round(point).astype(int)
    return 0 <= y < mask.shape[0] and 0 <= x < mask.shape[1] and mask[y, x] > 0.5


@pytest.mark.parametrize("kind", ["wood", "skin wall", "texture", "beige gradient", "wood and skin",
                                  "wood and poster"])
def test_face_on_a_skin_coloured_background(performer, kind):
    _on_background(performer, kind)


@pytest.mark.parametrize("kind", ["wood", "wood and poster"])
def test_a_face_the_equalised_cascade_misses_on_wood(performer_b, kind):
    """performer_b's face in front of wood: the whole frame's histogram equalisation spends its grey levels on
    the boards, and the cascade finds the face only in the grey levels as filmed."""
    _on_background(performer_b, kind)


@pytest.mark.parametrize("who", ["performer", "performer_b"])
def test_a_face_and_a_wooden_wall_in_one_warm_light(request, who):
    """The face and the wood behind it in one warm light (:data:`WARM`): the face is as orange as the boards; the
    cascade's window on it shows the skin models little skin as filmed and none in the light evened out over the
    frame (the wood turns grey, and the face with it). The window is tried in the light that gives its middle an
    average skin's colour as well, and its candidates need the likeness of a crop without skin."""
    _on_background(request.getfixturevalue(who), "wood", light=WARM)


def _on_background(performer, kind, light=(1.0, 1.0, 1.0)):
    frames, ref, skin = performer
    rng = np.random.default_rng(7)
    h, w = frames[0].shape[:2]
    wide = kind.startswith("wood and")
    shape = (h, WIDE, 3) if wide else frames[0].shape
    dx = (WIDE - w) // 2 if wide else 0          # the clip's frame sits in the canvas' middle
    back = background(kind, shape, skin, rng)
    tracker = ColorTracker()
    nme, found = [], 0
    for i, (rgb, r) in enumerate(zip(frames, ref, strict=True)):
        r = r + [dx, 0]
        canvas = np.zeros(shape, np.float32)
        canvas[:, dx:dx + w] = rgb
        m = face_mask(r, shape)[..., None]
        comp = np.clip((m * canvas + (1.0 - m) * back) * np.float32(light), 0, 255).astype(np.uint8)
        f = tracker.track(comp, 66 * i)
        if not f.valid:
            continue
        found += 1
        # Never on the background: both tracked eyes inside the face.
        for eye in eye_centres(f.curves):
            assert _inside(eye, m[..., 0]), (kind, i, eye)
        nme.append(curve_nme(f.curves, r))
    # Measured: every frame found, mean NME 0.027-0.03 for performer_c (0.02-0.03 on the clip as filmed).
    assert found == len(frames), (kind, found)
    assert np.mean(nme) < 0.035, (kind, np.mean(nme))


def _hand(shape, centre, size, skin, angle):
    """(H, W) float32 mask of a hand: a palm ellipse and four fingers and a thumb, ``size`` the palm's width."""
    m = np.zeros(shape[:2], np.float32)
    cx, cy = centre
    c, s = np.cos(np.radians(angle)), np.sin(np.radians(angle))

    def at(u, v):                         # hand coordinates (palm widths, up the fingers) -> image
        return (float(cx + size * (c * u - s * v)), float(cy + size * (s * u + c * v)))

    cv2.ellipse(m, (at(0, 0), (size, 1.15 * size), angle), 1.0, -1)
    for k, u in enumerate((-0.33, -0.11, 0.11, 0.33)):
        length = (0.75, 0.9, 0.85, 0.65)[k]
        cv2.ellipse(m, (at(u, -0.5 - length / 2), (0.2 * size, length * size), angle), 1.0, -1)
    cv2.ellipse(m, (at(0.6, -0.05), (0.22 * size, 0.6 * size), angle - 50.0), 1.0, -1)
    return cv2.GaussianBlur(m, (0, 0), 1.5)


def test_small_face_on_a_stage_with_a_hand_passing(performer_a):
    frames, ref, skin = performer_a
    rng = np.random.default_rng(3)
    (sw, sh), scale, (ox, oy) = STAGE
    back = background("stage", (sh, sw, 3), skin, rng)
    M = np.array([[scale, 0.0, ox], [0.0, scale, oy]])
    tracker = ColorTracker()
    n = len(frames)
    # The hand comes in from the right over the mouth and cheek in frames 20-39 and leaves again.
    passing = range(20, 40)
    shading = np.clip(skin[None, None] * 1.0, 0, 255)
    seen_err, covered, after = [], [], []
    for i, (rgb, r) in enumerate(zip(frames, ref, strict=True)):
        r = r * scale + [ox, oy]
        small = cv2.warpAffine(rgb, M, (sw, sh), flags=cv2.INTER_AREA)
        face = face_mask(r, (sh, sw))
        comp = face[..., None] * small + (1.0 - face[..., None]) * back
        hand = np.zeros((sh, sw), np.float32)
        if i in passing:
            t = (i - passing.start) / (len(passing) - 1)
            mouth = r[IDX["lip_upper_outer"]].mean(axis=0)
            unit = eye_distance(r)
            centre = mouth + [unit * (2.6 - 4.4 * np.sin(np.pi * t)), 0.5 * unit]
            hand = _hand((sh, sw), centre, 1.8 * unit, skin, -20.0)
            tone = shading * (0.9 + 0.1 * rng.random())
            comp = hand[..., None] * tone + (1.0 - hand[..., None]) * comp
        comp = np.clip(comp, 0, 255).astype(np.uint8)
        f = tracker.track(comp, 66 * i)
        hidden = float((face * hand).sum() / face.sum())
        if f.valid:                       # on the face, not carried off by the hand
            unit = eye_distance(r)
            err = np.linalg.norm(eye_centres(f.curves) - eye_centres(r), axis=1).max() / unit
            assert err < EYES_OFF, (i, err, hidden)
        if hidden < 0.1:
            assert f.valid, (i, hidden)
            (after if i >= passing.stop else seen_err).append(curve_nme(f.curves, r))
        elif hidden > 0.35:
            covered.append(f.valid)
    # Measured: the eyes within 0.24 eye distances of MediaPipe's while the hand passes (some of the mostly
    # covered frames not valid), NME 0.024 where the face is seen before and beside the hand, 0.036 after it
    # (0.02-0.027 for 15 frames, then 0.05-0.07 in the last five, as with the alignment's horizontal axis alone).
    assert covered, "the hand never covered the face"
    assert len(after) == n - passing.stop, len(after)
    assert np.mean(seen_err) < 0.045 and np.mean(after) < 0.04, (np.mean(seen_err), np.mean(after))


def _grey(rgb):
    """The frame as a monochrome camera (an infrared webcam, black-and-white footage) gives it: R = G = B."""
    return np.repeat(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)[..., None], 3, axis=2)


@pytest.mark.parametrize("who", ["performer", "performer_b"])
def test_a_face_filmed_in_grey(request, who):
    """No skin colour anywhere: the skin models find no region, and the face cascade's windows alone place the
    face (with the likeness a crop without skin needs); it is found and followed near MediaPipe's curves of the
    colour frames."""
    frames, ref, _ = request.getfixturevalue(who)
    tracker = ColorTracker()
    nme = []
    for i, (rgb, r) in enumerate(zip(frames, ref, strict=True)):
        f = tracker.track(_grey(rgb), 66 * i)
        assert f.valid, (who, i)
        nme.append(curve_nme(f.curves, r))
    # Measured: mean NME 0.035 (performer_c) and 0.037 (performer_b); no frame found while the cascade's windows
    # needed skin.
    assert np.mean(nme) < 0.045, (who, np.mean(nme))


def test_a_grey_scene_without_a_face_is_no_face():
    """A grey, warm blotchy texture without a face (no skin anywhere, so every window of the face cascade is a
    candidate): in the shifted copies where the cascade finds a window, a fresh tracker (whose first frame runs the
    cascade over the whole frame) finds no face."""
    rng = np.random.default_rng(11)
    back = background("texture", (480, 640, 3), np.array([190.0, 140.0, 120.0]), rng)
    seen = 0
    for i in range(40):
        grey = _grey(np.clip(np.roll(back, (7 * i, 11 * i), axis=(0, 1)), 0, 255).astype(np.uint8))
        if not face_windows(grey, None):
            continue
        seen += 1
        assert not ColorTracker().track(grey, 0).valid, i
    assert seen >= 3, seen                  # measured: windows in 5 of the 40 copies


def test_grey_eyes_are_not_drawn_into_their_sockets(performer_a):
    """Grey footage of a face whose eye sockets are shadowed: without colour, Eq. 1's intensity is the darkness
    alone and the sockets' shading rises with the eyes; the eye search reads a C of stronger contrast there, so
    the eyes found stay on the eyes and the face frame keeps its size."""
    frames, ref, _ = performer_a
    tracker = ColorTracker()
    nme, eyes_off, size = [], [], []
    for i, (rgb, r) in enumerate(zip(frames, ref, strict=True)):
        f = tracker.track(_grey(rgb), 66 * i)
        assert f.valid, i
        nme.append(curve_nme(f.curves, r))
        unit = eye_distance(r)
        eyes_off.append(np.linalg.norm(eye_centres(f.curves) - eye_centres(r), axis=1).mean() / unit)
        size.append(eye_distance(f.curves) / unit)
    # Measured: the eyes 0.060 eye distances off MediaPipe's on the colour frames (mean), the eye distance
    # 0.94 of theirs (median), NME 0.050; with the usual contrast for the eyes 0.139, 0.82 and 0.075.
    assert np.mean(eyes_off) < 0.09 and np.median(size) > 0.9, (np.mean(eyes_off), np.median(size))
    assert np.mean(nme) < 0.06, np.mean(nme)


def _with_beard(rgb, curves, rng):
    """The frame with a dark moustache (from under the nostrils down to the upper lip) and a short beard (from
    just under the lower lip to the chin) painted around the curves ``curves`` (C, 4, 2), of speckled hair."""
    right, left = eye_centres(curves)
    unit = float(np.linalg.norm(left - right))
    upper = bezier_points(curves[IDX["lip_upper_outer"]], 12)
    lower = bezier_points(curves[IDX["lip_lower_outer"]], 12)
    nose = np.concatenate([bezier_points(curves[IDX[n]], 4) for n in ("nostril_right", "nostril_left")])
    down = np.array([0.0, unit])
    moustache = np.concatenate([nose + 0.05 * down, upper[::-1]])
    mid = 0.5 * (upper[0] + upper[-1])
    beard = np.concatenate([lower + 0.08 * down, [mid + [0.45 * unit, 0.95 * unit], mid + [-0.45 * unit, 0.95 * unit]]])
    mask = np.zeros(rgb.shape[:2], np.float32)
    for poly in (moustache, beard):
        cv2.fillPoly(mask, [np.round(poly).astype(np.int32)], 1.0, cv2.LINE_AA)
    cover = (cv2.GaussianBlur(mask, (0, 0), 1.5) * rng.uniform(0.6, 0.95, mask.shape))[..., None]
    return np.clip(cover * np.array([48.0, 36.0, 30.0]) + (1.0 - cover) * rgb, 0, 255).astype(np.uint8)


def test_lips_under_a_moustache_and_over_a_beard(performer):
    """Dark hair above and below the lips lights Eq. 1's intensity as the lips do and joins the mouth's blob; it
    is told from the lips by its colour (less red than the cheeks), so the outer lips stay on the lips."""
    frames, ref, _ = performer
    rng = np.random.default_rng(5)
    tracker = ColorTracker()
    lips = ("lip_upper_outer", "lip_lower_outer", "lip_upper_inner", "lip_lower_inner")
    err = []
    for i, (rgb, r) in enumerate(zip(frames, ref, strict=True)):
        f = tracker.track(_with_beard(rgb, r, rng), 66 * i)
        assert f.valid, i
        span = np.linalg.norm(r[IDX["eye_left_upper"], 3] - r[IDX["eye_right_upper"], 3])
        err.append([np.linalg.norm(bezier_points(r[IDX[n]], 9)[:, None] - bezier_points(f.curves[IDX[n]], 64)[None],
                                   axis=-1).min(axis=1).mean() / span for n in lips])
    err = np.mean(err, axis=0)
    # Measured: NME 0.030 / 0.032 / 0.028 / 0.025 (upper and lower outer, upper and lower inner); with the hair
    # in the blob 0.036 / 0.048 / 0.043 / 0.048.
    assert err[0] < 0.033 and err.mean() < 0.035, err


#: A deep complexion's cheek colour (RGB) the ``_deep`` copies bring each performer's skin to.
DEEP_SKIN = (80.0, 60.0, 48.0)


def _deep(rgb, skin):
    """The frame as it would show a performer of a deep complexion: the pixels of the performer's skin chroma
    (within 15 levels of the cheeks' Cr and Cb, feathered over 10 more) scaled channel by channel so that the
    cheeks' colour ``skin`` (3,) becomes :data:`DEEP_SKIN` (the lips, close to the skin's chroma, darken with
    it; the eyes' white, the hair and the background do not)."""
    ycc = cv2.cvtColor(rgb, cv2.COLOR_RGB2YCrCb).astype(np.float32)
    ref = cv2.cvtColor(np.uint8([[np.clip(skin, 0, 255)]]), cv2.COLOR_RGB2YCrCb)[0, 0].astype(np.float32)
    near = np.ones(rgb.shape[:2], np.float32)
    for k in (1, 2):
        near *= np.clip(1.0 - np.maximum(np.abs(ycc[..., k] - ref[k]) - 15.0, 0.0) / 10.0, 0.0, 1.0)
    m = cv2.GaussianBlur(near, (0, 0), 2.0)[..., None]
    gains = np.asarray(DEEP_SKIN) / np.maximum(np.asarray(skin, dtype=float), 1.0)
    return np.clip(rgb * (m * gains + (1.0 - m)) + 0.5, 0, 255).astype(np.uint8)


@pytest.mark.parametrize("who", ["performer", "performer_b"])
def test_a_deep_complexion(request, who):
    """A performer of deep skin in front of a lighter wall: Eq. 1's colour terms (magenta, the lips' hue) are
    ratios of small, noisy numbers on skin of a low value, and the generic weights go over to the darkness
    (:data:`~facepuppet.capture.color.transform.DARK_WEIGHTS`); the face is found at its size and followed near
    MediaPipe's curves of the frames as filmed."""
    frames, ref, skin = request.getfixturevalue(who)
    tracker = ColorTracker()
    nme, size = [], []
    for i, (rgb, r) in enumerate(zip(frames, ref, strict=True)):
        f = tracker.track(_deep(rgb, skin), 66 * i)
        assert f.valid, (who, i)
        nme.append(curve_nme(f.curves, r))
        size.append(eye_distance(f.curves) / eye_distance(r))
    # Measured: performer_c NME 0.039, eye distance 0.91 of MediaPipe's (median); performer_b 0.047 and 1.23
    # (its face, pulled back hair beside a light wall, is taken a little large); with the generic weights kept
    # on the dark skin 0.038 / 0.89 and 0.281 / 1.83 (the eyes' search drawn out to the wall beside the face).
    assert np.mean(nme) < 0.055 and 0.85 < np.median(size) < 1.35, (who, np.mean(nme), np.median(size))


def _side_lit(rgb, curves, shade_right):
    """The frame lit from one side (a window beside the performer): the light falls to 0.25 across the face, a
    logistic step at the eyes' midpoint 0.3 eye-centre distances wide, towards the image's right (or left)."""
    right, left = eye_centres(curves)
    d = float(np.linalg.norm(left - right))
    x = (np.arange(rgb.shape[1], dtype=np.float32) - 0.5 * float(right[0] + left[0])) / (0.3 * d)
    light = 0.25 + 0.75 / (1.0 + np.exp(x if shade_right else -x))
    return np.clip(rgb * light[None, :, None] + 0.5, 0, 255).astype(np.uint8)


@pytest.mark.parametrize("who,shade_right", [("performer", True), ("performer", False), ("performer_a", False),
                                             ("performer_b", False)])
def test_a_face_lit_from_one_side(request, who, shade_right):
    """One half of the face in shade: Eq. 1 reads the shade as darkness, a feature, under one skin level for the
    whole crop; the light is evened out between the cheeks (:mod:`~facepuppet.capture.color.sides`), and the face
    is followed at its size near MediaPipe's curves of the frames as lit."""
    frames, ref, _ = request.getfixturevalue(who)
    tracker = ColorTracker()
    nme, size = [], []
    for i, (rgb, r) in enumerate(zip(frames, ref, strict=True)):
        f = tracker.track(_side_lit(rgb, r, shade_right), 66 * i)
        assert f.valid, (who, i)
        nme.append(curve_nme(f.curves, r))
        size.append(eye_distance(f.curves) / eye_distance(r))
    # Measured: NME 0.020 / 0.019 (performer_c shaded right / left), 0.027 (performer_a), 0.035 (performer_b, eye
    # distance 1.12 of MediaPipe's); with one skin level for the whole crop performer_c lost the face on 14 of the
    # 60 frames shaded right and was found on none shaded left, performer_a was tracked at 0.177 and performer_b at
    # 0.057, 1.24 times too large.
    assert np.mean(nme) < 0.045 and 0.85 < np.median(size) < 1.2, (who, np.mean(nme), np.median(size))


def _two_lights(rgb, curves, warm_left):
    """The frame lit by a warm lamp (R, G, B scaled 1.15, 1.0, 0.75) on one side and a cooler, dimmer light (0.6,
    0.7, 0.85) on the other, a logistic step at the eyes' midpoint 0.3 eye-centre distances wide."""
    right, left = eye_centres(curves)
    d = float(np.linalg.norm(left - right))
    x = (np.arange(rgb.shape[1], dtype=np.float32) - 0.5 * float(right[0] + left[0])) / (0.3 * d)
    s = (1.0 / (1.0 + np.exp(x if warm_left else -x)))[:, None]
    light = s * np.float32([1.15, 1.0, 0.75]) + (1.0 - s) * np.float32([0.6, 0.7, 0.85])
    return np.clip(rgb * light[None] + 0.5, 0, 255).astype(np.uint8)


def _from_above(rgb):
    """The frame lit from above (the light falling linearly from 1 at its top row to 0.4 at its bottom one), as a
    camera codes it (JPEG, quality 90)."""
    lit = np.clip(rgb * np.linspace(1.0, 0.4, rgb.shape[0], dtype=np.float32)[:, None, None] + 0.5, 0, 255)
    ok, coded = cv2.imencode(".jpg", cv2.cvtColor(lit.astype(np.uint8), cv2.COLOR_RGB2BGR),
                             [cv2.IMWRITE_JPEG_QUALITY, 90])
    assert ok
    return cv2.cvtColor(cv2.imdecode(coded, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)


@pytest.mark.parametrize("who,warm_left", [("performer", True), ("performer", False), ("performer_b", True),
                                           ("performer_b", False)])
def test_a_face_in_two_lights(request, who, warm_left):
    """A warm lamp on one side and a cool window's light on the other: Eq. 1's colour terms differ between the
    halves; the crops are brought to the lit side's colour (:func:`~facepuppet.capture.color.sides.evened_colours`),
    and the face is found within three frames and followed at its size."""
    frames, ref, _ = request.getfixturevalue(who)
    nme, size = followed(frames, ref, lambda rgb, r: _two_lights(rgb, r, warm_left), who, settle=3)
    # Measured: NME 0.037 / 0.030 (performer_c warm on the left / right: found at the third frame), 0.041 / 0.052
    # (performer_b, 1.12 / 1.23 times MediaPipe's eye distance); without the colours evened performer_c was tracked
    # at 0.130, 0.76 of its size, and on the right found only at the eighth frame and off the face (0.998), and
    # performer_b at 0.043 / 0.113 (1.40 times too large).
    assert nme < 0.055 and 0.85 < size < 1.25, (who, nme, size)


@pytest.mark.parametrize("who", ["performer", "performer_b"])
def test_a_face_lit_from_above(request, who):
    """A light from above: performer_b's eyeliner wings and the hair's edge beside her eyes, lit against the face,
    draw the first search's eyes apart at each step; the cascade's window holds the face's size
    (:data:`~facepuppet.capture.color.acquire.WINDOW_REACH`)."""
    frames, ref, _ = request.getfixturevalue(who)
    nme, size = followed(frames, ref, lambda rgb, r: _from_above(rgb), who)
    # Measured: NME 0.019 (performer_c, unchanged), 0.034 (performer_b, 1.10 times MediaPipe's eye distance);
    # without the window's reach performer_b was found 1.27 times too large and tracked at 0.047.
    assert nme < 0.045 and 0.85 < size < 1.2, (who, nme, size)

