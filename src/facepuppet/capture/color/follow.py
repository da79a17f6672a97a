"""Following the face between frames: the face crop aligned on a reference crop of the acquisition (ECC).

The search starts where the alignment put the face in the last frame, so a couple of steps suffice; the eyes
then correct the result (:class:`~facepuppet.capture.color.tracker.ColorTracker`).

Conventions: crop matrices (2, 3) map image pixels to crop pixels; the aligned crops are grey float32 at
``scale`` times the tracker's crop resolution.
"""

from __future__ import annotations

import cv2
import numpy as np

from facepuppet.capture.color.config import FollowConfig
from facepuppet.capture.color.face import CROP_EXTENT, FaceFrame, then_affine

__all__ = ["Follower", "ECC_EPS", "ECC_BLUR"]

# Tuning constants       unit          what it does
ECC_EPS = 1e-3           # correlation   the alignment's convergence tolerance (ECC)
ECC_BLUR = 3             # pixels        Gaussian blur of the alignment's images (ECC)


class Follower:
    """The alignment of each frame's face crop on the reference crop taken when the face was acquired.

    Parameters
    ----------
    size : (int, int)
        Width and height of the tracker's face crop, pixels.
    px : float
        Crop pixels per face unit.
    config : FollowConfig
    """

    def __init__(self, size: tuple[int, int], px: float, config: FollowConfig):
        self.size = size
        self.px = px
        self.config = config
        self.origin_px = -np.asarray(CROP_EXTENT[:2], dtype=float) * px   # the face frame's origin, crop pixels
        #: (h, w) float32 grey reference crop, or None before an acquisition.
        self.ref: np.ndarray | None = None
        #: Crop matrix (2, 3) where the alignment last put the face.
        self.followed: np.ndarray | None = None
        #: The last alignment's correlation of the aligned crop with the reference (ECC's criterion, in [-1, 1]),
        #: or None when it failed.
        self.correlation: float | None = None

    def reset(self) -> None:
        """Forget the reference (the face is being acquired afresh)."""
        self.ref = None

    def start(self, rgb: np.ndarray, frame: FaceFrame) -> None:
        """Take the reference crop of ``frame`` in the RGB frame (H, W, 3) uint8."""
        self.followed = frame.crop_matrix(self.px)
        self.ref = self.grey(rgb, self.followed)

    def grey(self, rgb: np.ndarray, A: np.ndarray) -> np.ndarray:
        """The face crop of crop matrix ``A`` at ``config.scale`` resolution, grey, float32."""
        w, h = self.size
        f = self.config.scale
        small = cv2.warpAffine(rgb, A * f, (int(w * f), int(h * f)), flags=cv2.INTER_LINEAR,
                               borderMode=cv2.BORDER_REPLICATE)
        return cv2.cvtColor(small, cv2.COLOR_RGB2GRAY).astype(np.float32)

    def follow(self, rgb: np.ndarray, A: np.ndarray) -> FaceFrame | None:
        """The face frame moved by aligning the face crop of crop matrix ``A`` on the reference (affine ECC),
        or None when the alignment fails."""
        # First guess: the face where the alignment last put it (reference half-res crop -> current one).
        f = self.config.scale
        guess = then_affine(cv2.invertAffineTransform(self.followed), A)
        guess[:, 2] *= f
        self.correlation = None
        try:
            cc, warp = cv2.findTransformECC(self.ref, self.grey(rgb, A), guess.astype(np.float32),
                                           cv2.MOTION_AFFINE, (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS,
                                                               self.config.iterations, ECC_EPS), None, ECC_BLUR)
        except cv2.error:
            return None
        self.correlation = float(cc)
        W = warp.astype(float)
        W[:, 2] /= f
        G = then_affine(W, cv2.invertAffineTransform(A))      # crop pixels -> image pixels, where the face is now
        self.followed = cv2.invertAffineTransform(G)
        px = self.px
        return FaceFrame(G[:, :2] @ self.origin_px + G[:, 2], G[:, 0] * px)
