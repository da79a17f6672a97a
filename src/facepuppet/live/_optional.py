"""Optional packages of the ``live`` extra, imported on first use with an error that names the fix."""

from __future__ import annotations

import importlib
from types import ModuleType

__all__ = ["import_extra"]

#: The pip command that installs every package the live outputs need.
INSTALL_HINT = 'pip install "facepuppet[live]"'


def import_extra(module: str, what: str) -> ModuleType:
    """Import ``module`` (a package of the ``live`` extra) or raise ImportError naming the pip install.

    Parameters
    ----------
    module : str
        Module to import, e.g. ``"pythonosc.udp_client"``.
    what : str
        The feature that needs it, for the message (``"the VMC sender"``).
    """
    try:
        return importlib.import_module(module)
    except ImportError as e:
        raise ImportError(f"{what} needs the package {module.split('.')[0]!r}: {INSTALL_HINT}") from e
