"""Arguments no command can use, refused before any command runs (one line, exit 1).

Text must be storable (no NUL, no lone surrogate: what undecodable bytes of an argument
become), numbers finite and integers within 64 bits. Paths are left alone: a file name may
hold any bytes.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any

import click

from toaster.errors import InvalidInputError
from toaster.model import check_text

_MAX_INT = 2**63 - 1


def _name(param: click.Parameter) -> str:
    """``subject`` for ``--subject``, ``agent`` for ``AGENT`` (as messages name values)."""
    if isinstance(param, click.Option) and param.opts:
        return max(param.opts, key=len).lstrip("-")
    return (param.name or "argument").lower()


def _check(param: click.Parameter, value: Any) -> None:
    if isinstance(value, tuple):
        for item in value:
            _check(param, item)
    elif isinstance(value, str):
        check_text(value, _name(param))
    elif isinstance(value, float) and not math.isfinite(value):
        msg = f"invalid {_name(param)} {value!r}: give a finite number"
        raise InvalidInputError(msg)
    elif isinstance(value, int) and not isinstance(value, bool) and abs(value) > _MAX_INT:
        msg = f"invalid {_name(param)} {value}: give an integer below 2^63"
        raise InvalidInputError(msg)


def _checked(callback: Callable[..., Any], params: list[click.Parameter]) -> Callable[..., Any]:
    checked = [p for p in params if p.name and not isinstance(p.type, click.Path | click.File)]

    @functools.wraps(callback)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        for param in checked:
            _check(param, kwargs.get(param.name or ""))
        return callback(*args, **kwargs)

    return wrapper


def guard(command: click.Command) -> None:
    """Check the arguments of ``command`` (and of every subcommand) before it runs."""
    if command.callback is not None and not getattr(command, "_toaster_guarded", False):
        command.callback = _checked(command.callback, command.params)
        command._toaster_guarded = True  # type: ignore[attr-defined]
    if isinstance(command, click.Group):
        for sub in command.commands.values():
            guard(sub)


def parse_time_option(value: str | None, flag: str, *, base_ns: int = 0) -> int | None:
    """``--at`` / ``--from`` / ``--to`` text as ns (None stays None); errors name ``flag``."""
    from toaster.timeutil import parse_time

    if value is None:
        return None
    try:
        return parse_time(value, base_ns=base_ns)
    except InvalidInputError as exc:
        msg = f"{flag}: {exc}"
        raise InvalidInputError(msg) from None


def parse_duration_option(value: str, flag: str) -> int:
    """A non-negative duration option (``--until 20s``) as ns; errors name ``flag``."""
    from toaster.timeutil import parse_duration

    try:
        duration = parse_duration(value)
    except InvalidInputError as exc:
        msg = f"{flag}: {exc}"
        raise InvalidInputError(msg) from None
    if duration < 0:
        msg = f"{flag} {value!r} must not be negative"
        raise InvalidInputError(msg)
    return duration


def parse_json_option(value: str, flag: str, *, usage: str | None = None) -> Any:
    """A JSON option value (``VALUE`` of tolerance, beliefs config), checked like a file.
    Text that is not JSON stays text, or is a usage error saying ``usage`` when given."""
    from toaster.documents import parse_text
    from toaster.errors import FileFormatError

    try:
        return parse_text(value, flag, json_only=True)
    except FileFormatError as exc:
        if "not valid JSON" not in str(exc):
            raise InvalidInputError(str(exc)) from None
        if usage is not None:
            raise click.UsageError(usage) from None
        return value
