"""Arguments no command can use, refused before any command runs (one line, exit 1).

Text must be storable (no NUL, no lone surrogate: what undecodable bytes of an argument
become), numbers finite and integers within 64 bits. Paths are left alone: a file name may
hold any bytes.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import click

from toaster.errors import InvalidInputError
from toaster.model import check_text

if TYPE_CHECKING:
    from toaster.timeutil import TimeFrame

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


def _checked(
    callback: Callable[..., Any], params: list[click.Parameter], path: str
) -> Callable[..., Any]:
    checked = [p for p in params if p.name and not isinstance(p.type, click.Path | click.File)]

    @functools.wraps(callback)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        from toaster.cli.context import one_line
        from toaster.cli.extras import check_extras

        try:
            for param in checked:
                _check(param, kwargs.get(param.name or ""))
            check_extras(path, kwargs)
            return callback(*args, **kwargs)
        except Exception as exc:  # one line also when the command runs without the group
            error = one_line(click.get_current_context(), exc)
            if error is None:
                raise
            raise error from None

    return wrapper


def guard(command: click.Command, path: str | None = None) -> None:
    """Check the arguments of ``command`` (and of every subcommand) before it runs, and the
    optional extras they need (:mod:`toaster.cli.extras`); its expected errors are one line
    (:func:`toaster.cli.context.one_line`). ``path``: the command as typed after ``toaster``
    (None: ``command`` is the ``toaster`` group)."""
    if command.callback is not None and not getattr(command, "_toaster_guarded", False):
        command.callback = _checked(command.callback, command.params, path or "")
        command._toaster_guarded = True  # type: ignore[attr-defined]
    if isinstance(command, click.Group):
        for name, sub in command.commands.items():
            guard(sub, f"{path} {name}" if path else name)


def parse_time_option(
    value: str | None, flag: str, *, frame: TimeFrame | None = None
) -> int | None:
    """``--at`` / ``--from`` / ``--to`` text as ns (None stays None); errors name ``flag``.

    A duration (``12.5s``) counts from the start of ``frame``, by default the data of the
    command's database (:func:`command_frame`, read only when needed);
    ``-5m`` is five minutes ago; ns, ISO dates and ``now`` as they are (docs/time.md).
    """
    from toaster.timeutil import counts_from_start, parse_time

    if value is None:
        return None
    try:
        if frame is None and counts_from_start(value):
            frame = command_frame()
        return parse_time(value, start_ns=frame.start_ns if frame is not None else None)
    except InvalidInputError as exc:
        msg = f"{flag}: {exc}"
        raise InvalidInputError(msg) from None


def command_frame() -> TimeFrame | None:
    """The time frame of the running command's database, in the ``--time`` style (the
    command's ``AppContext``: ``db`` and ``time_style``); None outside a command."""
    ctx = click.get_current_context(silent=True)
    while ctx is not None and not hasattr(type(ctx.obj), "db"):
        ctx = ctx.parent
    if ctx is None:
        return None
    app = ctx.obj
    frame: TimeFrame = app.db.time_frame(getattr(app, "time_style", "auto"))
    return frame


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
