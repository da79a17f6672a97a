"""The performer profile: what the colour tracker learns about one performer, saved as a versioned .npz.

A profile holds the colour-weight network of §3.1 (its layer arrays; rebuilt without pickle), the lips' hue
function G, the performer's skin colour, and the performer's mean feature layout in the face frame (curves in
face units, see :mod:`facepuppet.capture.color.face`) with the blob anchors the tracker aligns the face frame on.
:func:`default_profile` is a generic adult face with generic weights; it needs no training and no
MediaPipe. :func:`~facepuppet.capture.color.train.train_profile` learns a performer's profile from labelled frames.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field, replace

import numpy as np

from facepuppet._util.atomic import atomic_path
from facepuppet.capture.color.face import SkinModel
from facepuppet.capture.color.transform import DARK_WEIGHTS, DEFAULT_WEIGHTS, LipHue
from facepuppet.capture.curves import CURVE_NAMES
from facepuppet.errors import FacepuppetError

__all__ = [
    "PROFILE_VERSION",
    "GENERIC_LAYOUT",
    "GENERIC_ANCHORS",
    "GENERIC_MOUTH_REACH",
    "ANCHOR_NAMES",
    "Profile",
    "default_profile",
    "save_profile",
    "load_profile",
]

log = logging.getLogger(__name__)

PROFILE_VERSION = 1

# Average adult layout in face units (origin between the eye centres, unit = eye-centre distance, x towards
# the performer's left eye, y down the face); left half, mirrored for the right. Rounded anthropometric
# proportions: eye fissure 0.45 wide, brow 0.3 above the eye line, nose base 0.8 and mouth corners 1.2 below.
_LEFT_LAYOUT: dict[str, tuple[tuple[float, float], ...]] = {
    "brow_left": ((0.23, -0.29), (0.44, -0.33), (0.75, -0.47), (0.91, -0.25)),
    "eye_left_upper": ((0.276, 0.019), (0.377, -0.114), (0.607, -0.144), (0.724, -0.019)),
    "eye_left_lower": ((0.276, 0.019), (0.418, 0.035), (0.608, 0.096), (0.724, -0.019)),
    "nostril_left": ((0.0, 0.80), (0.08, 0.83), (0.17, 0.81), (0.22, 0.74)),
}
_MIDDLE_LAYOUT: dict[str, tuple[tuple[float, float], ...]] = {
    "lip_upper_outer": ((-0.39, 1.21), (-0.27, 0.96), (0.27, 0.96), (0.39, 1.21)),
    "lip_lower_outer": ((-0.39, 1.21), (-0.277, 1.556), (0.277, 1.556), (0.39, 1.21)),
    "lip_upper_inner": ((-0.35, 1.21), (-0.165, 1.10), (0.165, 1.10), (0.35, 1.21)),
    "lip_lower_inner": ((-0.35, 1.21), (-0.162, 1.334), (0.162, 1.334), (0.35, 1.21)),
}


def _generic_layout() -> np.ndarray:
    out = {}
    for name, pts in _LEFT_LAYOUT.items():
        p = np.asarray(pts, dtype=float)
        out[name] = p
        mirror = p * [-1.0, 1.0]
        # Right-side curves run in the same anatomical direction (inner to outer) except the nostril, which
        # runs from the ala to the nose base (iBUG 31-33).
        out[name.replace("left", "right")] = mirror[::-1] if name.startswith("nostril") else mirror
    out.update({k: np.asarray(v, dtype=float) for k, v in _MIDDLE_LAYOUT.items()})
    return np.stack([out[n] for n in CURVE_NAMES])


#: (C, 4, 2) generic feature curves in face units, CURVE_NAMES order.
GENERIC_LAYOUT = _generic_layout()

#: Blob anchors the face frame is aligned on: where, in face units, the tracker expects the centre of each
#: eye blob's box and the centroid of the nostrils.
ANCHOR_NAMES = ("eye_right", "eye_left", "nose")
GENERIC_ANCHORS = np.array([[-0.5, -0.03], [0.5, -0.03], [0.0, 0.78]])

#: Farthest the colour tracker lets the mouth corners move from the layout's, face units, unless a profile
#: learned the performer's own reach (an average mouth's corners move about a tenth of the eye distance in a
#: smile; a pucker moves them further in).
GENERIC_MOUTH_REACH = 0.12


@dataclass(frozen=True)
class Profile:
    """A performer profile.

    Attributes
    ----------
    layout : (C, 4, 2) float
        Mean feature curves in face units.
    anchors : (3, 2) float
        Expected anchor positions in face units (:data:`ANCHOR_NAMES`).
    skin : SkinModel
    lip_hue : LipHue
    weights : (4,) float
        Eq. 1's weights when there is no network (or before its first estimate).
    net : dict of str -> ndarray
        The 11-10-4 network's arrays (see :mod:`facepuppet.capture.color.net`); empty for none.
    lids : dict of str -> ndarray
        The eyelid model's arrays (see :mod:`facepuppet.capture.color.lids`); empty for none (the rules alone).
    shapes : dict of str -> dict of str -> ndarray
        Per family (``"lips"``, ``"brow_left"``, ``"brow_right"``) the arrays of its shape model (see
        :mod:`facepuppet.capture.color.shape_models`); empty for none (the rules alone).
    head : dict of str -> ndarray
        The head-turn model's arrays (yaw and pitch from the look of the crop, see
        :mod:`facepuppet.capture.color.head_turn`); empty for none (the pose is solved upright).
    name : str
    mouth_reach : float
        Farthest the mouth corners move from the layout's, face units (:data:`GENERIC_MOUTH_REACH` unless
        learned from the performer's labelled frames).
    """

    layout: np.ndarray = field(default_factory=lambda: GENERIC_LAYOUT.copy())
    anchors: np.ndarray = field(default_factory=lambda: GENERIC_ANCHORS.copy())
    skin: SkinModel = SkinModel()
    lip_hue: LipHue = LipHue()
    weights: np.ndarray = field(default_factory=lambda: DEFAULT_WEIGHTS.copy())
    net: dict = field(default_factory=dict)
    lids: dict = field(default_factory=dict)
    shapes: dict = field(default_factory=dict)
    head: dict = field(default_factory=dict)
    name: str = "generic"
    mouth_reach: float = GENERIC_MOUTH_REACH

    @property
    def dark_weights(self) -> np.ndarray | None:
        """Eq. 1's weights for skin of a low value (:data:`~.transform.DARK_WEIGHTS`, which the generic weights
        go over to on a dark face, :func:`~.transform.dark_skin_weights`) for a profile of the generic weights
        and no network; None for any other (its weights are the performer's own)."""
        generic = not self.net and np.allclose(np.asarray(self.weights, dtype=float), DEFAULT_WEIGHTS)
        return DARK_WEIGHTS.copy() if generic else None


def default_profile() -> Profile:
    """The built-in generic profile: average adult proportions, generic weights, no network."""
    return Profile()


def save_profile(path: str | os.PathLike, profile: Profile) -> None:
    """Write ``profile`` as a versioned .npz (no pickle), atomically."""
    arrays = {
        "version": np.int64(PROFILE_VERSION),
        "name": np.str_(profile.name),
        "layout": np.asarray(profile.layout, dtype=np.float64),
        "anchors": np.asarray(profile.anchors, dtype=np.float64),
        "skin_mean": np.asarray(profile.skin.mean, dtype=np.float64),
        "skin_cov": np.asarray(profile.skin.cov, dtype=np.float64),
        "skin_threshold": np.float64(profile.skin.threshold),
        "lip_hue": np.array([profile.lip_hue.centre, profile.lip_hue.width, profile.lip_hue.min_saturation]),
        "weights": np.asarray(profile.weights, dtype=np.float64),
        "mouth_reach": np.float64(profile.mouth_reach),
    }
    for k, v in profile.net.items():
        arrays[f"net_{k}"] = np.asarray(v, dtype=np.float64)
    for k, v in profile.lids.items():
        arrays[f"lids_{k}"] = np.asarray(v, dtype=np.float64)
    for family, model in profile.shapes.items():
        for k, v in model.items():
            arrays[f"shapes_{family}_{k}"] = np.asarray(v, dtype=np.float64)
    for k, v in profile.head.items():
        arrays[f"head_{k}"] = np.asarray(v, dtype=np.float64)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)


def _shapes(data: dict, path) -> dict:
    """The shape models of a profile file's ``shapes_<family>_<array>`` keys, checked against the families."""
    from facepuppet.capture.color.shape_models import FAMILIES, PATCH_SIZE

    out: dict = {}
    for key, value in data.items():
        if key.startswith("shapes_"):
            family, _, name = key[len("shapes_"):].rpartition("_")
            out.setdefault(family, {})[name] = value
    n_in = PATCH_SIZE[0] * PATCH_SIZE[1] * 3
    for family, model in out.items():
        n_out = len(FAMILIES.get(family, ())) * 8
        coef, intercept = model.get("coef"), model.get("intercept")
        if (family not in FAMILIES or coef is None or intercept is None or coef.shape != (n_out, n_in)
                or intercept.shape != (n_out,)):
            raise FacepuppetError(f"{path}: the profile's {family!r} shape model is damaged or of another kind")
    return out


def _head(data: dict, path) -> dict:
    """The head-turn model of a profile file's ``head_<array>`` keys (empty if none), checked."""
    from facepuppet.capture.color.head_turn import check_turn_model

    head = {k[5:]: v for k, v in data.items() if k.startswith("head_")}
    if not head:
        return {}
    try:
        model = check_turn_model(head, str(path))
    except ValueError as e:
        raise FacepuppetError(str(e)) from e
    if not model:
        log.warning("%s: the profile's head-turn model is of an older kind and is not used (the head's yaw and "
                    "pitch are read off the nose, as without a profile); train the profile again to use it", path)
    return model


#: The members of a profile file with a fixed shape (``name`` is a string; ``net_``, ``lids_``, ``shapes_``
#: and ``head_`` members are the optional models' arrays).
_MEMBER_SHAPES = {"version": (), "layout": GENERIC_LAYOUT.shape, "anchors": GENERIC_ANCHORS.shape,
                  "skin_mean": np.shape(SkinModel().mean), "skin_cov": np.shape(SkinModel().cov),
                  "skin_threshold": (), "lip_hue": (3,),
                  "weights": DEFAULT_WEIGHTS.shape, "mouth_reach": ()}
_MODEL_PREFIXES = ("net_", "lids_", "shapes_", "head_")
#: Bytes one member of a profile file may hold (its largest, a shape model, is about a megabyte).
PROFILE_MEMBER_BYTES = 64 << 20


def _checked(data: dict, path) -> None:
    """Raise FacepuppetError naming ``path`` and the member when a member is not the plain array it must be."""
    for key, value in data.items():
        if key == "name":
            if value.dtype.kind != "U" or value.shape != ():
                raise FacepuppetError(f"{path}: the profile's name must be one string, got {value.dtype} "
                                      f"of shape {value.shape}")
            continue
        if value.dtype.kind not in "fiu":
            raise FacepuppetError(f"{path}: the profile's {key!r} must hold numbers, not {value.dtype}")
        if key in _MEMBER_SHAPES and value.shape != _MEMBER_SHAPES[key]:
            raise FacepuppetError(f"{path}: the profile's {key!r} must have shape {_MEMBER_SHAPES[key]}, got "
                                  f"{value.shape}")
        if not np.isfinite(value).all():
            raise FacepuppetError(f"{path}: the profile's {key!r} holds values that are not finite")
    net = {k[4:]: v for k, v in data.items() if k.startswith("net_")}
    if net:
        from facepuppet.capture.color.net import ColourNet

        try:
            ColourNet.from_arrays(net)
        except ValueError as e:
            raise FacepuppetError(f"{path}: {e}") from e
    lids = {k[5:]: v for k, v in data.items() if k.startswith("lids_")}
    if lids:
        from facepuppet.capture.color.lids import PATCH_SIZE

        n = PATCH_SIZE[0] * PATCH_SIZE[1]
        if set(lids) != {"coef", "intercept"} or lids["coef"].shape != (2, n) or lids["intercept"].shape != (2,):
            raise FacepuppetError(f"{path}: the profile's eyelid model is damaged or of another kind")


def load_profile(path: str | os.PathLike) -> Profile:
    """Read a profile written by :func:`save_profile`.

    Only the members a profile has are read, each checked (header first, no pickle; see
    :func:`facepuppet._util.npz.read_npz`) and then for its kind and shape.

    Raises
    ------
    FacepuppetError
        If the file is missing, unreadable, truncated, of a future version, lacks a field or holds a member
        of the wrong kind or shape.
    """
    from facepuppet._util.npz import read_npz

    try:
        data = read_npz(path, "profile file", known=(*_MEMBER_SHAPES, "name"), prefixes=_MODEL_PREFIXES,
                        member_bytes=PROFILE_MEMBER_BYTES)
    except FacepuppetError as e:
        if isinstance(e.__cause__, FileNotFoundError):
            raise FacepuppetError(f"{path}: no such profile file (make one from a clip of the performer with "
                                  f"'facepuppet calibrate CLIP --make-profile {path} ...')") from e
        raise
    version = data.get("version")
    if version is not None and version.dtype.kind in "iu" and version.shape == () and int(version) > PROFILE_VERSION:
        raise FacepuppetError(f"{path}: profile version {int(version)} is newer than this facepuppet reads "
                              f"({PROFILE_VERSION}); upgrade facepuppet")
    _checked(data, path)
    try:
        version = int(data["version"])
        if version > PROFILE_VERSION:
            raise FacepuppetError(f"{path}: profile version {version} is newer than this facepuppet reads "
                                  f"({PROFILE_VERSION}); upgrade facepuppet")
        hue = data["lip_hue"]
        cov = data["skin_cov"]
        return Profile(
            layout=data["layout"].astype(np.float64),
            anchors=data["anchors"].astype(np.float64),
            skin=SkinModel(tuple(map(float, data["skin_mean"])), tuple(tuple(map(float, r)) for r in cov),
                           float(data["skin_threshold"])),
            lip_hue=LipHue(float(hue[0]), float(hue[1]), float(hue[2])),
            weights=data["weights"].astype(np.float64),
            net={k[4:]: v for k, v in data.items() if k.startswith("net_")},
            lids={k[5:]: v for k, v in data.items() if k.startswith("lids_")},
            shapes=_shapes(data, path),
            head=_head(data, path),
            name=str(data["name"]),
            # a profile file without a learned reach has the generic one
            mouth_reach=float(data.get("mouth_reach", GENERIC_MOUTH_REACH)),
        )
    except KeyError as e:
        raise FacepuppetError(f"{path}: profile file lacks the field {e.args[0]!r}") from e


def with_layout(profile: Profile, layout: np.ndarray, anchors: np.ndarray) -> Profile:
    """A copy of ``profile`` with a new layout and anchors."""
    return replace(profile, layout=np.asarray(layout, dtype=float), anchors=np.asarray(anchors, dtype=float))
