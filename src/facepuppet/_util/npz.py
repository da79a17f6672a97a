"""Reading the project's versioned ``.npz`` files (track, key expressions, rig, mapper) without pickle.

Every reader needs the same care: a missing file, a file that is not a zip archive, a truncated archive, or
an object array (which would need pickle) become one :class:`FacepuppetError` naming the file, and a file of
another kind or of a newer version than this facepuppet reads is refused with a message saying so.
"""

from __future__ import annotations

import os
import zipfile
import zlib

import numpy as np

from facepuppet.errors import FacepuppetError

__all__ = ["read_npz", "check_format"]


def read_npz(path: str | os.PathLike, what: str) -> dict[str, np.ndarray]:
    """Every array of an ``.npz`` file, read eagerly with ``allow_pickle=False``.

    Parameters
    ----------
    path : str or PathLike
    what : str
        What the file should be ("rig file", ...), for the error message.

    Raises
    ------
    FacepuppetError
        If the file is missing or cannot be read as an ``.npz`` archive of plain arrays.
    """
    try:
        data = np.load(path, allow_pickle=False)
        if not isinstance(data, np.lib.npyio.NpzFile):
            raise ValueError("a single array, not an .npz archive")
        with data:
            return {k: data[k] for k in data.files}
    except FileNotFoundError as e:
        raise FacepuppetError(f"{path}: no such file") from e
    except IsADirectoryError as e:
        raise FacepuppetError(f"{path}: is a folder, not a {what}") from e
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error) as e:
        raise FacepuppetError(f"{path}: cannot read {what} ({e})") from e


def check_format(arrays: dict[str, np.ndarray], path: str | os.PathLike, what: str, fmt: str,
                 version: int) -> int:
    """Check an archive's ``format`` and ``version`` entries; returns the file's version.

    Raises
    ------
    FacepuppetError
        If ``format`` is not ``fmt``, ``version`` is missing or not an integer, or it is newer than
        ``version`` (the newest this facepuppet reads).
    """
    if str(arrays.get("format", "")) != fmt:
        raise FacepuppetError(f"{path}: not a facepuppet {what} (format is not {fmt!r})")
    try:
        found = int(arrays["version"])
    except (KeyError, TypeError, ValueError) as e:
        raise FacepuppetError(f"{path}: {what} has no valid version") from e
    if found > version:
        raise FacepuppetError(f"{path}: {what} version {found} is newer than this facepuppet reads ({version}); "
                              f"upgrade facepuppet")
    return found
