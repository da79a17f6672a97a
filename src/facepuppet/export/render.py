"""A small CPU mesh renderer (numpy + OpenCV): flat Lambert shading, back-face culling, depth sorting.

It draws the character of a preview video and the pictures of key-models; it needs no GPU and no system
library. Triangles facing away are dropped, the rest are painted far to near (the painter's algorithm, by each
triangle's mean depth) with OpenCV's sub-pixel convex-polygon fill, each in one colour: ambient plus Lambert
diffuse light on its base colour.

Conventions: mesh coordinates are y up, +z towards the default viewer (a right-handed frame, like glTF); the
image is RGB uint8, x right, y down. Faces are wound counter-clockwise seen from outside.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ["Camera", "Light", "render_mesh"]

_SHIFT = 4  # sub-pixel bits of the polygon fill
_DEFAULT_COLOR = (0.75, 0.75, 0.75)


def _rotation(yaw: float, pitch: float) -> np.ndarray:
    """World-to-view rotation of a viewer that turned ``yaw`` about y, then ``pitch`` about x (radians)."""
    cy, sy, cp, sp = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch)
    ry = np.array([[cy, 0.0, -sy], [0.0, 1.0, 0.0], [sy, 0.0, cy]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cp, sp], [0.0, -sp, cp]])
    return rx @ ry


@dataclass(frozen=True)
class Camera:
    """Where a mesh is seen from and how it lands in the image.

    View coordinates are ``(v - center) @ rotation.T``: x right, y up, z towards the viewer. Orthographic
    when ``distance`` is None, else a pinhole at ``distance`` mesh units in front of ``center``.

    Attributes
    ----------
    center : (3,) float
        Mesh point that lands in the middle of the image.
    scale : float
        Pixels per mesh unit (at ``center``'s depth for a perspective camera).
    size : (int, int)
        Image width and height in pixels.
    rotation : (3, 3) float
        World-to-view rotation.
    distance : float or None
        Distance of the pinhole from ``center``; None for an orthographic view.
    """

    center: np.ndarray
    scale: float
    size: tuple[int, int] = (480, 480)
    rotation: np.ndarray | None = None
    distance: float | None = None

    @classmethod
    def fit(
        cls,
        vertices: np.ndarray,
        size: tuple[int, int] = (480, 480),
        *,
        margin: float = 0.08,
        yaw: float = 0.0,
        pitch: float = 0.0,
        distance: float | None = None,
    ) -> Camera:
        """A camera that frames ``vertices`` (V, 3), for example a neutral mesh, with a ``margin`` on each side.

        Use one camera for every frame of an animation so the framing does not change.

        Parameters
        ----------
        vertices : (V, 3) float
        size : (int, int)
            Image width and height.
        margin : float
            Fraction of the image left free on each side.
        yaw, pitch : float
            Viewing direction in radians (0, 0 looks at the mesh's front, along -z).
        distance : float, optional
            Perspective: distance of the pinhole from the centre, in multiples of the mesh's largest extent.
        """
        v = np.asarray(vertices, dtype=float)
        if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
            raise ValueError(f"vertices must have shape (V, 3) with V > 0, got {v.shape}")
        w, h = _check_size(size)
        rot = _rotation(yaw, pitch)
        view = v @ rot.T
        lo, hi = view.min(axis=0), view.max(axis=0)
        ext = np.maximum(hi - lo, 1e-9)
        scale = min(w * (1 - 2 * margin) / ext[0], h * (1 - 2 * margin) / ext[1])
        mid = (lo + hi) / 2.0
        dist = None
        if distance is not None:
            dist = float(distance) * float(ext.max())
            scale *= (dist - (hi[2] - mid[2])) / dist  # keep the nearest part inside the frame
        return cls(mid @ rot, float(scale), (w, h), rot, dist)

    def project(self, vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Image positions (V, 2) in pixels and depths (V,) (larger is nearer) of ``vertices`` (V, 3)."""
        view = np.asarray(vertices, dtype=float) - np.asarray(self.center, dtype=float)
        if self.rotation is not None:
            view = view @ np.asarray(self.rotation).T
        s = np.full(len(view), self.scale)
        if self.distance is not None:
            s = s * self.distance / np.maximum(self.distance - view[:, 2], 1e-6)
        w, h = self.size
        xy = np.empty((len(view), 2))
        xy[:, 0] = w / 2.0 + s * view[:, 0]
        xy[:, 1] = h / 2.0 - s * view[:, 1]
        return xy, view[:, 2]

    def view_directions(self, vectors: np.ndarray) -> np.ndarray:
        """Rotate direction vectors (N, 3) from mesh into view coordinates."""
        vec = np.asarray(vectors, dtype=float)
        return vec if self.rotation is None else vec @ np.asarray(self.rotation).T


@dataclass(frozen=True)
class Light:
    """A directional light in view coordinates plus ambient light.

    Attributes
    ----------
    direction : (3,) float
        Towards the light, view coordinates (x right, y up, z to the viewer); normalised on use.
    ambient, diffuse : float
        Shade = ambient + diffuse * max(0, n · l), times the base colour.
    """

    direction: tuple[float, float, float] = (-0.35, 0.5, 0.8)
    ambient: float = 0.35
    diffuse: float = 0.7


def _check_size(size) -> tuple[int, int]:
    try:
        w, h = (int(s) for s in size)
    except (TypeError, ValueError) as err:
        raise ValueError(f"size must be (width, height), got {size!r}") from err
    if w <= 0 or h <= 0:
        raise ValueError(f"size must be positive, got {size!r}")
    return w, h


def _base_colors(colors, n_vertices: int, faces: np.ndarray) -> np.ndarray:
    """Per-face base colours (T, 3) in [0, 1] from per-vertex (V, 3) or per-face (T, 3) colours."""
    if colors is None:
        return np.broadcast_to(np.asarray(_DEFAULT_COLOR), (len(faces), 3))
    c = np.asarray(colors)
    if c.shape == (3,):
        c = np.broadcast_to(c, (len(faces), 3))
    scale = 255.0 if c.dtype == np.uint8 else 1.0
    c = c.astype(float) / scale
    if c.shape == (n_vertices, 3):
        return c[faces].mean(axis=1)
    if c.shape == (len(faces), 3):
        return c
    raise ValueError(f"colors must have shape (V, 3) = ({n_vertices}, 3), (T, 3) = ({len(faces)}, 3) or (3,), "
                     f"got {c.shape}")


def render_mesh(
    vertices: np.ndarray,
    faces: np.ndarray,
    *,
    size: tuple[int, int] | None = None,
    camera: Camera | None = None,
    colors: np.ndarray | None = None,
    light: Light | None = None,
    background: tuple[int, int, int] | np.ndarray = (38, 40, 48),
    cull: bool = True,
) -> np.ndarray:
    """Render a triangle mesh into an RGB image.

    Parameters
    ----------
    vertices : (V, 3) float
        Vertex positions, y up, +z towards the default viewer.
    faces : (T, 3) int
        Triangles, counter-clockwise seen from outside.
    size : (int, int), optional
        Image width and height; default ``camera.size`` or 480 x 480.
    camera : Camera, optional
        Default :meth:`Camera.fit` on these vertices (pass one camera to keep an animation's framing still).
    colors : (V, 3) or (T, 3) or (3,) float in [0, 1] or uint8, optional
        Per-vertex or per-face base colours; default light grey.
    light : Light, optional
        Default :class:`Light` ().
    background : (3,) int or (H, W, 3) uint8
        Background colour, or an image to draw over (not modified).
    cull : bool
        Drop triangles facing away from the viewer (right for closed meshes).

    Returns
    -------
    (H, W, 3) uint8
        RGB image.
    """
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"vertices must have shape (V, 3), got {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3 or not np.issubdtype(f.dtype, np.integer):
        raise ValueError(f"faces must be an integer array of shape (T, 3), got {f.dtype} {f.shape}")
    if len(f) and (f.min() < 0 or f.max() >= len(v)):
        raise ValueError(f"faces index vertices 0..{len(v) - 1}, got {f.min()}..{f.max()}")
    if camera is None:
        camera = Camera.fit(v, size or (480, 480))
    w, h = _check_size(size or camera.size)
    if (w, h) != tuple(camera.size):
        raise ValueError(f"size {size} differs from the camera's size {camera.size}")
    light = light or Light()

    if isinstance(background, np.ndarray) and background.ndim == 3:
        if background.shape != (h, w, 3) or background.dtype != np.uint8:
            raise ValueError(f"background image must be uint8 of shape ({h}, {w}, 3), got "
                             f"{background.dtype} {background.shape}")
        img = background.copy()
    else:
        img = np.empty((h, w, 3), np.uint8)
        img[:] = np.asarray(background, dtype=np.uint8)
    if len(f) == 0:
        return img

    xy, depth = camera.project(v)
    p = xy[f]  # (T, 3, 2)
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    area = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]  # negative: counter-clockwise on screen (y down)
    keep = area < 0 if cull else area != 0
    view = camera.view_directions(v)
    q = view[f[keep]]
    normal = np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
    if not cull:
        normal *= np.sign(normal[:, 2:3] + 1e-12)  # two-sided: shade the side that faces the viewer
    to_light = np.asarray(light.direction, dtype=float)
    to_light = to_light / np.linalg.norm(to_light)
    shade = light.ambient + light.diffuse * np.clip(normal @ to_light, 0.0, None)
    rgb = _base_colors(colors, len(v), f)[keep] * shade[:, None]
    rgb = np.clip(rgb * 255.0 + 0.5, 0, 255).astype(np.int32)

    order = np.argsort(depth[f[keep]].mean(axis=1), kind="stable")  # far to near
    pts = np.round(p[keep][order] * (1 << _SHIFT)).astype(np.int32)
    fill = cv2.fillConvexPoly
    line = cv2.LINE_8
    for poly, col in zip(pts, rgb[order].tolist(), strict=True):
        fill(img, poly, col, line, _SHIFT)
    return img
