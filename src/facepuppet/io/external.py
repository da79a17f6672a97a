"""Files a glTF asset refers to (buffer and image URIs), read only where they may be.

A ``.gltf`` names its buffers by URI. Only a relative reference to a regular file in the asset's own folder
or below it is followed: no absolute path, no ``..`` part, no scheme other than ``data:`` (decoded by the
reader itself), no symbolic link leading out of the folder, no device, FIFO or folder; and only the
``byteLength`` bytes the asset declares are read (a larger file is cut there, a smaller one is refused).
"""

from __future__ import annotations

import os
import stat
import urllib.parse
from pathlib import Path, PurePosixPath

from facepuppet.errors import FacepuppetError

__all__ = ["read_external"]


def read_external(asset: str | os.PathLike, uri: str, byte_length: int, what: str) -> bytes:
    """The first ``byte_length`` bytes of the file ``uri`` names, relative to ``asset``'s folder.

    Parameters
    ----------
    asset : str or PathLike
        The ``.gltf`` file.
    uri : str
        Its (percent-encoded) URI.
    byte_length : int
        Bytes the asset declares.
    what : str
        For the message ("buffer 0").

    Raises
    ------
    FacepuppetError
        Naming ``asset`` and the URI, if the reference leaves the folder, names no regular file, or holds
        fewer than ``byte_length`` bytes.
    """
    asset = Path(asset)
    label = f"{asset}: {what} URI {uri[:80]!r}"
    if byte_length is None or int(byte_length) < 0:
        raise FacepuppetError(f"{label}: no valid byteLength")
    byte_length = int(byte_length)
    parsed = urllib.parse.urlsplit(uri)
    if parsed.scheme or parsed.netloc or parsed.query or parsed.fragment:
        raise FacepuppetError(f"{label}: only relative file names and data: URIs are read")
    rel = urllib.parse.unquote(parsed.path)
    parts = PurePosixPath(rel).parts
    if not rel or "\x00" in rel or rel.startswith(("/", "\\")) or any(p in ("..", "") for p in parts) \
            or any("\\" in p or ":" in p for p in parts):
        raise FacepuppetError(f"{label}: must name a file in the asset's own folder (no absolute path, no '..')")
    folder = asset.resolve().parent
    file = folder.joinpath(*parts)
    real = Path(os.path.realpath(file))
    if folder not in real.parents:
        raise FacepuppetError(f"{label}: leads out of the asset's folder")
    try:
        st = os.stat(real)
    except OSError as e:
        raise FacepuppetError(f"{asset}: cannot read {what.split()[0]} file {rel} ({what}: {e.strerror})") from e
    if not stat.S_ISREG(st.st_mode):
        raise FacepuppetError(f"{label}: not a regular file")
    if st.st_size < byte_length:
        raise FacepuppetError(f"{asset}: {what} holds {st.st_size} bytes, needs {byte_length} (file {rel})")
    try:
        with open(real, "rb") as f:
            data = f.read(byte_length)
    except OSError as e:
        raise FacepuppetError(f"{asset}: cannot read {what.split()[0]} file {rel} ({what}: {e.strerror})") from e
    if len(data) < byte_length:
        raise FacepuppetError(f"{asset}: {what} holds {len(data)} bytes, needs {byte_length} (file {rel})")
    return data
