"""Reading the project's versioned ``.npz`` files (track, key expressions, rig, mapper) without pickle.

Every reader needs the same care: a missing file, a file that is not a zip archive, a truncated archive, or
an object array (which would need pickle) become one :class:`FacepuppetError` naming the file, and a file of
another kind or of a newer version than this facepuppet reads is refused with a message saying so.

A hostile archive is read as little as possible: only the members the format knows are opened (an unknown
member is never inflated), and each member's ``.npy`` header (shape, dtype) is read first and checked against
:data:`LIMITS` before its data is inflated, so a header claiming 10^12 values or a small file inflating to
gigabytes is refused without allocating. Members that hold text in every format (:func:`is_text_member`: names,
formats, backends, hashes) must say so in their header and stay within ``LIMITS["text_bytes"]``, so a name
list swapped for a huge numeric array is refused before it is inflated (or turned into strings one by one).
"""

from __future__ import annotations

import math
import os
import stat
import zipfile
import zlib
from collections.abc import Iterable, Mapping

import numpy as np

from facepuppet.errors import FacepuppetError

__all__ = ["read_npz", "check_format", "is_text_member", "LIMITS"]

#: Sane bounds of one archive: bytes of one member's array, of all arrays together, members in the archive,
#: bytes of one text member (names, format, backend, hashes).
LIMITS = {"member_bytes": 1 << 30, "total_bytes": 2 << 30, "members": 10_000, "text_bytes": 16 << 20}
#: Last parts (after a ``prefix.``) of member names that hold text in every facepuppet format.
_TEXT_NAMES = frozenset({"format", "backend", "name", "method", "solver", "profile_hash", "media_hash"})


def is_text_member(name: str) -> bool:
    """Whether member ``name`` holds text in every facepuppet format (names, formats, backends, hashes)."""
    last = name.rpartition(".")[2]
    return last in _TEXT_NAMES or last.endswith("names")


def _header(f) -> tuple[tuple[int, ...], bool, np.dtype]:
    version = np.lib.format.read_magic(f)
    if version == (1, 0):
        return np.lib.format.read_array_header_1_0(f)
    if version == (2, 0):
        return np.lib.format.read_array_header_2_0(f)
    raise ValueError(f"unsupported .npy version {version}")


def _read_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, name: str, budget: list[int],
                 limit: int, most: int | None) -> np.ndarray:
    with zf.open(info) as f:
        shape, fortran, dtype = _header(f)
        if dtype.hasobject:
            raise ValueError(f"member {name!r} holds Python objects (would need pickle)")
        if any(int(n) < 0 for n in shape):
            raise ValueError(f"member {name!r} has a negative shape {shape}")
        count = math.prod(int(n) for n in shape)
        if most is not None and count > most:
            raise ValueError(f"member {name!r} holds {count} values (shape {shape}), the format has at most {most}")
        nbytes = count * dtype.itemsize
        if is_text_member(name):
            if dtype.kind not in "US":
                raise ValueError(f"member {name!r} must hold text, not {dtype}")
            limit = min(limit, LIMITS["text_bytes"])
        if nbytes > limit:
            raise ValueError(f"member {name!r} claims {nbytes} bytes (shape {shape}), more than "
                             f"{limit} this reader accepts")
        if nbytes > info.file_size:
            raise ValueError(f"member {name!r} claims {nbytes} bytes but holds {info.file_size} (truncated)")
        budget[0] -= nbytes
        if budget[0] < 0:
            raise ValueError(f"the arrays add up to more than {LIMITS['total_bytes']} bytes")
        arr = np.empty(math.prod(int(n) for n in shape), dtype=dtype)
        view = memoryview(arr).cast("B")
        got = 0
        while got < nbytes:                      # inflated straight into the array: one copy in memory
            n = f.readinto(view[got:])
            if not n:
                raise ValueError(f"member {name!r} is truncated")
            got += n
        return arr.reshape(shape[::-1]).T.copy() if fortran else arr.reshape(shape)


def read_npz(path: str | os.PathLike, what: str, *, known: Iterable[str] | None = None,
             prefixes: Iterable[str] = (), member_bytes: int | None = None,
             sizes: Mapping[str, int] | None = None) -> dict[str, np.ndarray]:
    """The arrays of an ``.npz`` file the format knows, read with their headers checked first (no pickle).

    Parameters
    ----------
    path : str or PathLike
    what : str
        What the file should be ("rig file", ...), for the error message.
    known : iterable of str, optional
        The member names the format has; others are skipped unread. None reads every member.
    prefixes : iterable of str
        Members whose names start with one of these are known too (``mapper.``, ``option_``).
    member_bytes : int, optional
        The format's own bound on one member's bytes, below ``LIMITS["member_bytes"]`` (a format of small
        arrays refuses a big one before inflating it).
    sizes : mapping of str to int, optional
        The most values the format allows in some members (a scalar member 1, a frame size 2): a header
        claiming more is refused before its data is inflated.

    Raises
    ------
    FacepuppetError
        If the file is missing, not a regular file, or cannot be read as an ``.npz`` archive of plain arrays
        within :data:`LIMITS`.
    """
    known = None if known is None else set(known)
    prefixes = tuple(prefixes)
    limit = LIMITS["member_bytes"] if member_bytes is None else min(int(member_bytes), LIMITS["member_bytes"])
    try:
        st = os.stat(path)
    except FileNotFoundError as e:
        raise FacepuppetError(f"{path}: no such file") from e
    except OSError as e:
        raise FacepuppetError(f"{path}: cannot read {what} ({e.strerror})") from e
    if stat.S_ISDIR(st.st_mode):
        raise FacepuppetError(f"{path}: is a folder, not a {what}")
    if not stat.S_ISREG(st.st_mode):
        raise FacepuppetError(f"{path}: not a regular file, not a {what}")
    try:
        with zipfile.ZipFile(path) as zf:
            infos = zf.infolist()
            if len(infos) > LIMITS["members"]:
                raise ValueError(f"{len(infos)} members, more than {LIMITS['members']}")
            out: dict[str, np.ndarray] = {}
            budget = [LIMITS["total_bytes"]]
            for info in infos:
                if not info.filename.endswith(".npy"):
                    continue
                name = info.filename[:-len(".npy")]
                if known is not None and name not in known and not name.startswith(prefixes):
                    continue
                if name in out:
                    raise ValueError(f"member {name!r} appears twice")
                out[name] = _read_member(zf, info, name, budget, limit, (sizes or {}).get(name))
            return out
    except MemoryError as e:
        raise FacepuppetError(f"{path}: cannot read {what} (out of memory)") from e
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error, NotImplementedError) as e:
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
