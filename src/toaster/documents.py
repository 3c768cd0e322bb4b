"""Reading the JSON and YAML files users hand to toaster (batches, scenarios), with one-line
errors that name the file, where it is wrong and the fix.

A document is checked as a whole before anyone uses it: UTF-8 text, valid syntax, at most
:data:`MAX_DEPTH` levels of nesting and :data:`MAX_NODES` values (YAML aliases counted as
often as they are used); YAML dates become ISO text. Loaders then check their own fields.
"""

from __future__ import annotations

import datetime as dt
import json
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import yaml

from toaster.errors import FileFormatError, InvalidInputError

#: Deepest nesting of lists and mappings a document may have.
MAX_DEPTH = 64
#: Most values (scalars, lists, mappings) a document may hold.
MAX_NODES = 2_000_000


@contextmanager
def located(where: str) -> Iterator[None]:
    """A bad value checked inside becomes a :class:`FileFormatError` naming ``where`` (the
    file and field) before the check's own one-line message."""
    try:
        yield
    except InvalidInputError as exc:
        msg = f"{where}: {exc}"
        raise FileFormatError(msg) from None


def read_document(path: str | Path, what: str = "file") -> Any:
    """Parse ``path`` as JSON (``.json``) or YAML (any other suffix), checked (see the module).

    Raises :class:`FileFormatError` ("cannot read scenario 'x.yaml': ..." for a missing or
    unreadable file, "... not valid YAML (line 3: ...): fix the syntax" for a parse error).
    """
    path = Path(path)
    label = f"{what} {str(path)!r}"
    try:
        raw = path.read_bytes()
    except OSError as exc:
        msg = f"cannot read {label}: {exc.strerror or exc}"
        raise FileFormatError(msg) from None
    try:
        body = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        msg = (
            f"cannot read {label}: not UTF-8 text (byte 0x{raw[exc.start]:02x} on line "
            f"{line}); save it as UTF-8"
        )
        raise FileFormatError(msg) from None
    return parse_text(body, label, json_only=path.suffix.lower() == ".json")


def parse_text(body: str, label: str, *, json_only: bool = False) -> Any:
    """Parse JSON (``json_only``) or YAML text, checked; errors start "cannot read LABEL"."""
    kind = "JSON" if json_only else "YAML"
    try:
        data = json.loads(body) if json_only else yaml.safe_load(body)
    except json.JSONDecodeError as exc:
        msg = f"cannot read {label}: not valid JSON (line {exc.lineno}: {exc.msg}): fix the syntax"
        raise FileFormatError(msg) from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f"line {mark.line + 1}: " if mark is not None else ""
        problem = (exc.problem or exc.context or "syntax error").strip().splitlines()[0]
        msg = f"cannot read {label}: not valid YAML ({where}{problem}): fix the syntax"
        raise FileFormatError(msg) from None
    except yaml.YAMLError as exc:
        msg = (
            f"cannot read {label}: not valid YAML ({str(exc).strip().splitlines()[0]}): "
            "fix the syntax"
        )
        raise FileFormatError(msg) from None
    except RecursionError:
        msg = f"cannot read {label}: nested too deep for {kind} (at most {MAX_DEPTH} levels)"
        raise FileFormatError(msg) from None
    except (ValueError, OverflowError) as exc:  # a number of thousands of digits
        msg = f"cannot read {label}: {str(exc).splitlines()[0]}: fix the value"
        raise FileFormatError(msg) from None
    return check_tree(data, label)


def check_tree(data: Any, label: str) -> Any:
    """``data`` with dates as ISO text, once its depth, size and value types are checked."""
    sizes: dict[int, int] = {}
    total = _size(data, label, sizes)
    if total > MAX_NODES:
        msg = f"cannot read {label}: {total} values (aliases expanded), at most {MAX_NODES}"
        raise FileFormatError(msg)
    return _plain(data, {})


def _size(root: Any, label: str, sizes: dict[int, int]) -> int:
    """How many values ``root`` holds, shared ones counted each time (iterative)."""
    stack: list[tuple[Any, int, bool]] = [(root, 1, False)]
    while stack:
        node, depth, done = stack.pop()
        if not isinstance(node, dict | list):
            if not isinstance(node, str | int | float | bool | dt.date | None):
                msg = (
                    f"cannot read {label}: {type(node).__name__} values are not supported; "
                    "use text, numbers, lists and mappings"
                )
                raise FileFormatError(msg)
            continue
        if id(node) in sizes and sizes[id(node)] > 0:
            continue
        if depth > MAX_DEPTH:
            msg = f"cannot read {label}: nested deeper than {MAX_DEPTH} levels; flatten it"
            raise FileFormatError(msg)
        children = list(node.values()) if isinstance(node, dict) else node
        if done:
            sizes[id(node)] = 1 + sum(sizes.get(id(c), 1) for c in children)
            continue
        if id(node) in sizes:  # on the current path: a recursive alias
            msg = f"cannot read {label}: a YAML alias refers to itself; remove the loop"
            raise FileFormatError(msg)
        sizes[id(node)] = 0
        stack.append((node, depth, True))
        stack.extend((child, depth + 1, False) for child in children)
    return sizes.get(id(root), 1)


def _plain(node: Any, seen: dict[int, Any]) -> Any:
    """A copy with YAML dates as text (shared sub-trees stay shared; depth is bounded)."""
    if isinstance(node, dt.date):
        return node.isoformat()
    if not isinstance(node, dict | list):
        return node
    if id(node) in seen:
        return seen[id(node)]
    if isinstance(node, list):
        out: Any = []
        seen[id(node)] = out
        out.extend(_plain(v, seen) for v in node)
    else:
        out = {}
        seen[id(node)] = out
        for key, value in node.items():
            out[_plain(key, seen)] = _plain(value, seen)
    return out
