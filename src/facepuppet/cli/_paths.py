"""Every command's file arguments checked together, before any work starts.

Each subcommand declares which of its arguments are files it reads and which it writes
(``parser.set_defaults(inputs=..., outputs=...)``: tuples of argparse ``dest`` names); :func:`check_args` then
refuses, with one line naming the argument and the path:

- an empty path (which ``pathlib`` would read as ``.``);
- a name that is not valid UTF-8 (OpenCV crashes on such names) or holds a NUL;
- an input that is a FIFO, a socket or a device (reading one blocks or never ends), or a symbolic link to one,
  or an input folder holding one;
- an output that exists and is not a regular file (a folder, a device node such as ``/dev/null``, a FIFO, a
  symbolic link to any of these): the atomic rename would replace it; an output (file or folder) among the
  system's special files (``/dev``, ``/proc``, ``/sys``, by name or through links; ``/dev/shm`` is ordinary);
- an output whose folder is missing or not writable, or whose temporary name (``.NAME.XXXXXXXX.SUFFIX``,
  :func:`facepuppet._util.atomic.atomic_path`) would be longer than the file system allows;
- an output that is the same file as an input or as another output: the same resolved path, or the same
  (device, inode) as an existing file (hard and symbolic links), or a file of an input folder (an OBJ
  character, an image folder).

Camera names (``camera:N``) and unset options are skipped.
"""

from __future__ import annotations

import contextlib
import os
import stat
from collections.abc import Iterable, Mapping
from pathlib import Path

from facepuppet.errors import FacepuppetError

__all__ = ["check_paths", "check_args", "describe", "TEMP_NAME_EXTRA"]

#: Characters the temporary name adds to an output's name: "." + "." + 8 random characters + a suffix of up
#: to 8 (``tempfile.mkstemp`` in ``atomic_path``).
TEMP_NAME_EXTRA = 2 + 8 + 8
#: Folders of special files: an output in one (by its name or through symbolic links) is refused whatever it
#: is; ``/dev/shm`` holds ordinary files.
_SPECIAL_TREES = ("/dev/", "/proc/", "/sys/")
_ORDINARY_IN_SPECIAL = ("/dev/shm/",)
#: Media given as a device rather than a file.
CAMERA_PREFIX = "camera:"


def describe(path: str) -> str:
    """``path`` printable on any terminal (bytes that are not UTF-8 shown as escapes)."""
    return path.encode("utf-8", "backslashreplace").decode("utf-8") if isinstance(path, str) else str(path)


def _kind(mode: int) -> str | None:
    """What a non-regular, non-folder file is, or None for a regular file or a folder."""
    for test, name in ((stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return None


def _check_name(label: str, path: str) -> None:
    if path == "":
        raise FacepuppetError(f"{label}: empty path")
    if "\x00" in path:
        raise FacepuppetError(f"{label} {describe(path)}: the name holds a NUL character")
    try:
        path.encode("utf-8")
    except UnicodeEncodeError as e:
        raise FacepuppetError(f"{label} {describe(path)}: the name is not valid UTF-8; rename the file") from e


def _identity(path: str) -> tuple[int, int] | None:
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_dev, st.st_ino


def _check_input(label: str, path: str) -> None:
    try:
        st = os.stat(path)
    except FileNotFoundError:
        if os.path.islink(path):
            raise FacepuppetError(f"{label} {describe(path)}: a symbolic link to nothing") from None
        return  # the reader says "no such file" in its own words
    except OSError as e:
        raise FacepuppetError(f"{label} {describe(path)}: {e.strerror}") from e
    kind = _kind(st.st_mode)
    if kind is not None:
        raise FacepuppetError(f"{label} {describe(path)}: is {kind}, not a file")


def _special(path: str) -> bool:
    """Whether absolute ``path`` is in (or is) one of the folders of special files."""
    path = path.rstrip("/") + "/"
    return path.startswith(_SPECIAL_TREES) and not path.startswith(_ORDINARY_IN_SPECIAL)


def _check_not_special(label: str, path: str) -> None:
    real = os.path.realpath(path)
    if _special(os.path.abspath(path)) or _special(real):
        where = "" if os.path.abspath(path) == real else f" (it leads to {describe(real)})"
        raise FacepuppetError(f"{label} {describe(path)}: is among the system's special files{where}; "
                              f"refusing to write there")


def _check_output(label: str, path: str, *, folder_output: bool = False) -> None:
    p = Path(path)
    if os.path.lexists(path):
        try:
            st = os.stat(path)
        except OSError:
            raise FacepuppetError(f"{label} {describe(path)}: a symbolic link to nothing; refusing to replace "
                                  f"it") from None
        special = next((hop for hop in _link_chain(path) if _special(hop)), None)
        if special is not None:
            raise FacepuppetError(f"{label} {describe(path)}: a symbolic link to {describe(special)}; refusing "
                                  f"to replace it")
        if folder_output:
            if not stat.S_ISDIR(st.st_mode):
                raise FacepuppetError(f"{label} {describe(path)}: exists and is not a folder")
            _check_not_special(label, path)
            return
        if stat.S_ISDIR(st.st_mode):
            raise FacepuppetError(f"{label} {describe(path)}: is a folder, not a file name")
        if not stat.S_ISREG(st.st_mode):
            raise FacepuppetError(f"{label} {describe(path)}: is {_kind(st.st_mode) or 'not a regular file'}; "
                                  f"refusing to replace it")
    _check_not_special(label, path)
    if folder_output:
        return
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise FacepuppetError(f"{label} {describe(path)}: folder {describe(str(folder))} does not exist")
    if not os.access(folder, os.W_OK):
        raise FacepuppetError(f"{label} {describe(path)}: folder {describe(str(folder))} is not writable "
                              f"(read-only or no permission)")
    try:
        name_max = os.pathconf(folder, "PC_NAME_MAX")
    except (OSError, ValueError):
        name_max = 255
    if len(os.fsencode(p.name)) + TEMP_NAME_EXTRA > name_max:
        raise FacepuppetError(f"{label} {describe(path)}: file name too long (at most "
                              f"{name_max - TEMP_NAME_EXTRA} bytes here)")


def _link_chain(path: str, limit: int = 40) -> list[str]:
    """The absolute targets of the symbolic links ``path`` leads through, hop by hop."""
    hops = []
    current = os.path.abspath(path)
    while os.path.islink(current) and len(hops) < limit:
        current = os.path.normpath(os.path.join(os.path.dirname(current), os.readlink(current)))
        hops.append(current)
    return hops


def _folder_files(path: str) -> list[str]:
    """The files directly in folder ``path`` (an input folder's members an output must not replace)."""
    try:
        return [e.path for e in os.scandir(path)]
    except OSError:
        return []


def check_paths(inputs: Mapping[str, str | None], outputs: Mapping[str, str | None], *,
                folder_outputs: Iterable[str] = ()) -> None:
    """Check the file arguments of one command (see the module notes).

    Parameters
    ----------
    inputs, outputs : mapping of label -> path or None
        Label as the user typed it (``"-o"``, ``"--rig"``, ``"MEDIA"``); None = not given.
    folder_outputs : iterable of str
        Labels of ``outputs`` that name a folder to write into (``demo -o``).

    Raises
    ------
    FacepuppetError
        One line naming the argument, the path and what is wrong.
    """
    folder_outputs = set(folder_outputs)
    ins = {k: str(v) for k, v in inputs.items() if v is not None}
    outs = {k: str(v) for k, v in outputs.items() if v is not None}
    for label, path in {**ins, **outs}.items():
        _check_name(label, path)
    ins = {k: v for k, v in ins.items() if not v.startswith(CAMERA_PREFIX)}
    for label, path in ins.items():
        _check_input(label, path)
    for label, path in outs.items():
        _check_output(label, path, folder_output=label in folder_outputs)
    # the files an output must not be: every input (and, for an input folder, its files), every other output
    taken: list[tuple[str, str]] = []
    for label, path in ins.items():
        taken.append((label, path))
        if os.path.isdir(path):
            members = _folder_files(path)
            for f in members:   # a reader of the folder (OBJ character, image folder) would block on a FIFO
                with contextlib.suppress(OSError):
                    kind = _kind(os.stat(f).st_mode)
                    if kind is not None:
                        raise FacepuppetError(f"{label} {describe(path)}: holds {describe(os.path.basename(f))}, "
                                              f"which is {kind}, not a file")
            taken += [(f"{label} (in folder {describe(path)})", f) for f in members]
    for label, path in outs.items():
        real = os.path.realpath(path)
        ident = _identity(path)
        for other_label, other in taken:
            if os.path.realpath(other) == real or (ident is not None and _identity(other) == ident):
                what = "the same file as" if other_label in outs else "the same file as the input"
                raise FacepuppetError(f"{label} {describe(path)}: is {what} {other_label} {describe(other)}; "
                                      f"refusing to overwrite it")
        taken.append((label, path))


def check_args(args) -> None:
    """:func:`check_paths` on an argparse namespace whose ``inputs`` / ``outputs`` name its file arguments.

    ``args.inputs`` and ``args.outputs`` are tuples of ``(dest, label)``; ``args.folder_outputs`` (optional)
    lists the dests of outputs that are folders.
    """
    inputs = {label: getattr(args, dest, None) for dest, label in getattr(args, "inputs", ())}
    outputs = {label: getattr(args, dest, None) for dest, label in getattr(args, "outputs", ())}
    folders = {label for dest, label in getattr(args, "outputs", ()) if dest in getattr(args, "folder_outputs", ())}
    check_paths(inputs, outputs, folder_outputs=folders)
