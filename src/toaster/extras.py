"""toaster's optional extras, checked before the work that needs them starts.

A command or library call that will need an extra calls :func:`require` first, so that a
missing package is one line naming ``pip install 'toaster[EXTRA]'`` before anything is read,
computed or written (not a failure after a whole run was stored).
"""

from __future__ import annotations

import importlib

from toaster.errors import MissingDependencyError

#: extra (as in ``pip install 'toaster[EXTRA]'``) -> the modules it provides
EXTRAS: dict[str, tuple[str, ...]] = {
    "plot": ("matplotlib",),
    "export": ("pyarrow",),
    "pandas": ("pandas",),
    "rosbag": ("rosbags",),
    "ros2": ("cyclonedds", "rosbags"),
    "foxglove": ("foxglove",),
}


def require(extra: str, feature: str) -> None:
    """Raise :class:`~toaster.errors.MissingDependencyError` (naming the pip command) unless
    every module of ``extra`` can be imported; ``feature`` says what needs it."""
    for module in EXTRAS[extra]:
        try:
            importlib.import_module(module)
        except ImportError:
            raise MissingDependencyError(module, extra, feature) from None
