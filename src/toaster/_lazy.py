"""A package's names loaded on first use (PEP 562), so that importing the package stays cheap.

A package declares its names twice, and ``tests/test_front_door.py`` checks both agree: under
``if TYPE_CHECKING:`` as imports (what type checkers and IDEs see, with their real types) and
in a mapping name -> defining module given to :func:`exports` (what runs)::

    if TYPE_CHECKING:
        from toaster.app.session import connect as connect
    _HOMES = {"connect": "toaster.app.session"}
    __all__ = sorted(_HOMES)
    if not TYPE_CHECKING:  # hidden from type checkers: a misspelt name stays an error
        __getattr__, __dir__ = exports(__name__, _HOMES)
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Mapping
from importlib import import_module
from typing import Any


def exports(
    package: str, homes: Mapping[str, str]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for ``package``. ``homes`` maps each name to the module that
    defines it, or to ``package.name`` itself for a submodule."""

    def getattr_(name: str) -> Any:
        home = homes.get(name)
        if home is None:
            msg = f"module {package!r} has no attribute {name!r}"
            raise AttributeError(msg)
        module = import_module(home)
        value = module if home == f"{package}.{name}" else getattr(module, name)
        setattr(sys.modules[package], name, value)  # later lookups skip this function
        return value

    def dir_() -> list[str]:
        return sorted({*vars(sys.modules[package]), *homes})

    return getattr_, dir_
