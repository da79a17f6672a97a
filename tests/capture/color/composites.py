"""The shared clips' frames composited for the colour tracker's tests: MediaPipe's curves of the frames as filmed,
the face cut out as an oval around its eyes and set on made-up scenes, and the measures the tests take.

Conventions: RGB frames; curves (C, 4, 2) in image pixels, in :data:`~facepuppet.capture.curves.CURVE_NAMES` order.
"""

import cv2
import numpy as np

from facepuppet.capture.color.tracker import ColorTracker
from facepuppet.capture.curves import CURVE_NAMES, bezier_points

IDX = {n: i for i, n in enumerate(CURVE_NAMES)}
MEASURED = [n for n in CURVE_NAMES if not n.startswith("nostril")]
#: The face cut out: an oval centred this far below the eyes, with these half-axes (eye-centre distances).
FACE_OVAL = (0.8, 1.2, 1.75)


def curve_nme(ours, ref):
    """Mean distance of the reference curves' points to ours (closest points), over the curves of :data:`MEASURED`, in
    the reference's outer eye-corner distance."""
    span = np.linalg.norm(ref[IDX["eye_left_upper"], 3] - ref[IDX["eye_right_upper"], 3])
    d = [np.linalg.norm(bezier_points(ref[IDX[n]], 9)[:, None] - bezier_points(ours[IDX[n]], 64)[None],
                        axis=-1).min(axis=1).mean() for n in MEASURED]
    return float(np.mean(d) / span)


def eye_centres(curves):
    """(right, left) eye centres (2, 2) of a frame's curves."""
    return np.stack([curves[IDX[f"eye_{s}_upper"]][[0, 3]].mean(axis=0) for s in ("right", "left")])


def eye_distance(curves):
    """The eye-centre distance of a frame's curves, pixels."""
    return float(np.linalg.norm(np.subtract(*eye_centres(curves))))


def face_mask(curves, shape):
    """(H, W) float32 in [0, 1]: the face's oval from the reference eyes, feathered: centred :data:`FACE_OVAL`
    [0] eye-centre distances below the eyes' midpoint, half-axes :data:`FACE_OVAL` [1:] of that distance."""
    right, left = eye_centres(curves)
    d = float(np.linalg.norm(left - right))
    across = (left - right) / d
    down = np.array([-across[1], across[0]])
    centre = 0.5 * (left + right) + FACE_OVAL[0] * d * down
    angle = float(np.degrees(np.arctan2(across[1], across[0])))
    m = np.zeros(shape[:2], np.float32)
    cv2.ellipse(m, (tuple(map(float, centre)), (2 * FACE_OVAL[1] * d, 2 * FACE_OVAL[2] * d), angle), 1.0, -1)
    return cv2.GaussianBlur(m, (0, 0), 3.0)


def poster(img, centre, d, skin):
    """Draw a face-like pattern (skin oval, dark eyes and brows, nostrils, a mouth line) of eye distance ``d``."""
    cx, cy = centre
    dark = tuple(float(v) for v in 0.3 * skin)
    cv2.ellipse(img, ((cx, cy + 0.8 * d), (2.4 * d, 3.5 * d), 0.0), tuple(float(v) for v in skin), -1)
    for s in (-1, 1):
        cv2.ellipse(img, ((cx + 0.5 * s * d, cy), (0.45 * d, 0.2 * d), 0.0), dark, -1)
        cv2.ellipse(img, ((cx + 0.5 * s * d, cy - 0.35 * d), (0.6 * d, 0.12 * d), 0.0), dark, -1)
        cv2.circle(img, (int(cx + 0.15 * s * d), int(cy + 0.75 * d)), max(1, int(0.06 * d)), dark, -1)
    cv2.ellipse(img, ((cx, cy + 1.15 * d), (0.8 * d, 0.15 * d), 0.0), tuple(float(v) for v in 0.5 * skin), -1)


def background(kind, shape, skin, rng):
    """(H, W, 3) float32 RGB background of ``kind``."""
    h, w = shape[:2]
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    grain = np.sin(x / 7.0 + 3.0 * np.sin(y / 40.0)) + 0.5 * np.sin(x / 2.3 + y / 90.0)
    wood = np.array([196.0, 140.0, 96.0])[None, None] * (1.0 + 0.12 * grain[..., None])
    if kind == "wood":
        img = wood
    elif kind == "skin wall":
        img = np.broadcast_to(skin, (h, w, 3)).astype(np.float32) * (0.9 + 0.2 * x[..., None] / w)
    elif kind == "texture":                 # blotchy warm texture with dark flecks
        noise = cv2.GaussianBlur(rng.normal(size=(h, w)).astype(np.float32), (0, 0), 9.0)
        noise /= noise.std() + 1e-6
        img = np.array([205.0, 150.0, 115.0])[None, None] * (1.0 + 0.15 * noise[..., None])
        flecks = cv2.GaussianBlur((rng.random((h, w)) < 0.002).astype(np.float32), (0, 0), 2.0) * 40.0
        img = img * (1.0 - np.clip(flecks, 0, 0.6))[..., None]
    elif kind == "beige gradient":          # a beige wall lit by a warm lamp on the left
        ramp = (1.25 - 0.55 * x / w)[..., None] * (1.0 - 0.15 * y / h)[..., None]
        img = np.array([214.0, 188.0, 160.0])[None, None] * ramp * np.array([1.0, 0.93, 0.8])
    elif kind in ("wood and skin", "wood and poster"):
        img = np.ascontiguousarray(wood, dtype=np.float32)
        d = 95.0
        if kind == "wood and skin":         # a face-sized, skin-coloured object: a bare arm's or a lampshade's size
            cv2.ellipse(img, ((120.0, 260.0), (2.4 * d, 3.4 * d), 10.0), tuple(float(v) for v in skin), -1)
        else:
            poster(img, (120.0, 200.0), d, skin)
    elif kind == "stage":                   # dark, with props: boxes and poles in dim, warm and grey tones
        img = np.full((h, w, 3), 28.0, np.float32) * (0.8 + 0.4 * y[..., None] / h)
        for _ in range(14):
            x0, y0 = int(rng.integers(0, w - 40)), int(rng.integers(0, h - 40))
            cv2.rectangle(img, (x0, y0), (x0 + int(rng.integers(20, 160)), y0 + int(rng.integers(10, 120))),
                          tuple(float(v) for v in rng.uniform(15, 110, 3)), -1)
        for _ in range(5):
            x0 = int(rng.integers(0, w))
            tone = tuple(float(v) for v in rng.uniform(40, 140, 3))
            cv2.line(img, (x0, 0), (x0 + int(rng.integers(-60, 60)), h), tone, int(rng.integers(2, 9)))
    else:
        raise ValueError(kind)
    img = img + rng.normal(0.0, 3.0, size=img.shape)
    return np.clip(img, 0, 255).astype(np.float32)


def clip_frames(path, first=0, last=None, step=1):
    """RGB frames ``first``, ``first + step``, ... (before ``last``, or to the end) of the video ``path``."""
    cap = cv2.VideoCapture(str(path))
    frames, k = [], 0
    while last is None or k < last:
        ok, bgr = cap.read()
        if not ok:
            break
        if k >= first and (k - first) % step == 0:
            frames.append(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
        k += 1
    cap.release()
    return frames


def mediapipe_reference(frames, face_landmarker):
    """MediaPipe's features (``FrameFeatures``, image mode: each frame on its own) of each frame; every frame must
    show the face."""
    from facepuppet.capture.tracking import make_tracker

    mp = make_tracker("mediapipe", model_path=face_landmarker, running_mode="image")
    try:
        ref = [mp.track(f, 66 * i) for i, f in enumerate(frames)]
    finally:
        mp.close()
    assert all(r.valid for r in ref)
    return ref


def performer_clip(assets, face_landmarker, name):
    """60 frames (every 2nd of the first 120) of ``name``, MediaPipe's curves and the face's skin colour."""
    frames = clip_frames(assets / "video" / f"{name}.mp4", 0, 120, 2)
    ref = np.stack([r.curves for r in mediapipe_reference(frames, face_landmarker)])
    # The cheeks' colour: below the eyes, beside the nose.
    c = ref[0]
    cheek = np.round(0.5 * (c[IDX["eye_right_lower"], 1] + c[IDX["lip_upper_outer"], 0])).astype(int)
    skin = frames[0][cheek[1] - 4:cheek[1] + 4, cheek[0] - 4:cheek[0] + 4].reshape(-1, 3).mean(axis=0)
    return frames, ref, skin


def followed(frames, ref, light, who, settle=0):
    """NME against MediaPipe's curves of the frames as lit, and the eye distance's median ratio to theirs, of the
    colour tracker following the frames in ``light`` (a function of the frame and its curves); every frame from
    the ``settle``-th on must be tracked."""
    tracker = ColorTracker()
    nme, size = [], []
    for i, (rgb, r) in enumerate(zip(frames, ref, strict=True)):
        f = tracker.track(light(rgb, r), 66 * i)
        assert f.valid or i < settle, (who, i)
        if f.valid:
            nme.append(curve_nme(f.curves, r))
            size.append(eye_distance(f.curves) / eye_distance(r))
    return float(np.mean(nme)), float(np.median(size))
