"""Data inside text that other programs interpret: one quoting rule per format, defined here.

Ids and values come from anyone who can publish on a ROS topic, record a bag, write a track
file or a batch, or insert a row into ``fact_inbox``. toaster writes them into gnuplot scripts,
matplotlib labels, CSV cells, JSON lines, shell command lines it prints and ROS names. Each
writer quotes through the function of its format, so that nothing a data source writes runs
code, breaks the file or hides what it is:

* :func:`visible`: one line showing every character (line breaks and control characters as
  backslash escapes); comments, terminal and tab-separated cells; :func:`label_text` for the
  labels of pictures (at most :data:`LABEL_CHARS` characters);
* gnuplot: :func:`gnuplot_label` (a label: single-quoted runs, no backquote substitution, no
  macro, no escape), :func:`gnuplot_string` (an exact string expression: file names),
  :func:`gnuplot_datum` (a double-quoted field of a data file), :func:`gnuplot_comment`;
* matplotlib: :func:`mpl_text` (no mathtext, shown in a legend);
* shell: :func:`shell_word`;
* CSV: :func:`csv_text` / :func:`csv_untext` (spreadsheet formulas neutralised, reversibly),
  :func:`csv_line`;
* JSON lines: :func:`json_line` (ASCII, strict JSON);
* ROS names: :func:`ros_name` / :func:`ros_id` (an injective map of ids onto name tokens).

SQL identifiers are quoted by :func:`toaster.db.views.quote_identifier`; values are always bound
parameters.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
import shlex
from typing import Any

from toaster.errors import InvalidInputError

# -- one visible line -----------------------------------------------------------------------
_ESCAPES = {"\\": "\\\\", "\n": "\\n", "\r": "\\r", "\t": "\\t"}
#: a backslash, C0 and C1 control characters, DEL, line and paragraph separators, bidi
#: controls (they reorder what is shown) and lone surrogates (not encodable as UTF-8)
_HIDDEN_CHARS = "\\\\\x00-\x1f\x7f-\x9f\u061c\u200e\u200f\u2028-\u202e\u2066-\u2069\ud800-\udfff"
_HIDDEN = re.compile(f"[{_HIDDEN_CHARS}]")


def _escape(match: re.Match[str]) -> str:
    char = match.group()
    code = ord(char)
    return _ESCAPES.get(char) or (f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}")


def visible(text: str) -> str:
    """``text`` on one line with every character visible: a backslash doubled, ``\\n``,
    ``\\r``, ``\\t``, other control characters, line separators and bidi controls as
    ``\\xhh`` / ``\\uhhhh`` (as Python writes them); other text unchanged."""
    if text.isascii() and text.isprintable() and "\\" not in text:
        return text
    return _HIDDEN.sub(_escape, text)


#: A label in a picture shows at most this many characters (a longer id: its start, then
#: "…" and its length; the data files hold it whole).
LABEL_CHARS = 120


def label_text(text: str) -> str:
    """What a picture's label shows of ``text``: :func:`visible`, cut to :data:`LABEL_CHARS`."""
    shown = visible(text)
    if len(shown) <= LABEL_CHARS:
        return shown
    return f"{shown[: LABEL_CHARS - 24]}… ({len(text)} characters)"


# -- gnuplot ----------------------------------------------------------------------------------
#: What gnuplot's line scanners look at inside strings: quotes, a backquote (command
#: substitution), ``@`` (macros), control characters (a line break ends the command). gnuplot
#: 5.4 takes a quote inside a double-quoted string for the end of a single-quoted one and then
#: expands a later ``@name``, so none of these is ever inside a string literal.
_GNUPLOT_SPLIT = re.compile("([`'\"@]|[\x00-\x1f\x7f\ud800-\udfff]+)")


def _octal(text: str) -> str:
    """``text`` as octal escapes of its UTF-8 bytes (a file name's undecodable bytes, kept by
    ``surrogateescape``, as themselves), as gnuplot reads them in double-quoted strings."""
    data = b"".join(
        bytes([ord(c) - 0xDC00])
        if "\udc80" <= c <= "\udcff"
        else c.encode("utf-8", "surrogatepass")
        for c in text
    )
    return "".join(f"\\{byte:03o}" for byte in data)


def _gnuplot_expression(text: str) -> str:
    """``text`` as a gnuplot string expression: single-quoted runs joined by ``.`` to
    ``sprintf("%c", code)`` for each quote, backquote and ``@``, and to octal escapes
    (double-quoted) of control characters and of the undecodable bytes of a file name
    (``surrogateescape``)."""
    parts: list[str] = []
    for run in _GNUPLOT_SPLIT.split(text):
        if not run:
            continue
        if len(run) == 1 and run in "`'\"@":
            parts.append(f'sprintf("%c", {ord(run)})')
        elif _GNUPLOT_SPLIT.fullmatch(run):
            parts.append(f'"{_octal(run)}"')
        else:
            parts.append(f"'{run}'")
    return " . ".join(parts) or "''"


def gnuplot_label(text: str, *, tic: bool = False) -> str:
    """A gnuplot string expression showing :func:`label_text` ``text`` (see
    :func:`_gnuplot_expression`: no backquote substitution, no macro, no escape). ``tic``: a
    tic label, which gnuplot reads as a format (``%`` doubled). Give the label ``noenhanced``
    so that ``^ _ @ & ~ { }`` show as they are."""
    shown = label_text(text)
    return _gnuplot_expression(shown.replace("%", "%%") if tic else shown)


def gnuplot_string(text: str) -> str:
    """A gnuplot string expression equal to ``text`` (a file name): as :func:`gnuplot_label`,
    with control characters and undecodable bytes as octal escapes."""
    return _gnuplot_expression(text)


_DATUM = re.compile(f'["{_HIDDEN_CHARS}]')


def gnuplot_datum(text: str) -> str:
    """A double-quoted field of a gnuplot data file, one column on one line, that gnuplot reads
    back as ``text`` (``strcol``): a backslash doubled, ``\\n``, ``\\r``, ``\\t``, and octal
    escapes for ``"`` (gnuplot ends the field at any ``"``), other control characters, line
    separators and bidi controls, as in gnuplot's double-quoted strings."""
    return '"' + _DATUM.sub(lambda m: _ESCAPES.get(m.group()) or _octal(m.group()), text) + '"'


def gnuplot_comment(text: str) -> str:
    """A comment line (``# ...``) of a gnuplot script or data file: :func:`visible` ``text``,
    and never a backslash at its end (gnuplot would join the next line to the comment)."""
    line = "# " + visible(text)
    return line + " " if line.endswith("\\") else line


# -- matplotlib -------------------------------------------------------------------------------
def mpl_text(text: str) -> str:
    """matplotlib text showing :func:`label_text` ``text`` as it is: every ``$`` escaped (no
    mathtext), a leading ``_`` after a space (a legend leaves out labels starting with ``_``).
    Draw it with ``text.usetex`` off (:mod:`toaster.outputs.plotting.render` does)."""
    shown = label_text(text).replace("$", "\\$")
    return " " + shown if shown.startswith("_") else shown


# -- shell ------------------------------------------------------------------------------------
def shell_word(text: str) -> str:
    """``text`` as one word of a POSIX shell command line toaster prints (a file name in
    ``gnuplot -p NAME``): quoted when needed, never expanded by the shell."""
    return shlex.quote(text)


# -- CSV --------------------------------------------------------------------------------------
#: First characters that make a spreadsheet read a cell as a formula (OWASP's CSV injection:
#: = + - @ tab and carriage return; a line feed and the full-width forms some locales
#: evaluate), and the quote that marks a neutralised cell.
FORMULA_START = ("=", "+", "-", "@", "\t", "\r", "\n", "\uff1d", "\uff0b", "\uff0d", "\uff20")
CSV_MARK = "'"


def csv_text(text: str) -> str:
    """A text cell a spreadsheet shows as text: ``'`` put before text starting with a formula
    character (:data:`FORMULA_START`) or with ``'`` itself, so that :func:`csv_untext` strips
    exactly one leading ``'`` to give ``text`` back. Numbers are not text: write them as
    numbers."""
    return CSV_MARK + text if text.startswith((*FORMULA_START, CSV_MARK)) else text


def csv_untext(cell: str) -> str:
    """The text a :func:`csv_text` cell holds (one leading ``'`` removed)."""
    return cell[1:] if cell.startswith(CSV_MARK) else cell


def csv_cells(values: Any) -> list[Any]:
    """A CSV row: text values through :func:`csv_text`, other values as they are."""
    return [csv_text(v) if isinstance(v, str) else v for v in values]


def csv_line(values: Any) -> str:
    """One CSV record (:func:`csv_cells`) without its line end, for output that ends lines with
    ``\\n``: a cell holding ``\\r`` or ``\\n`` is quoted (Python's csv quotes only the characters
    of its own line end)."""
    out = io.StringIO()
    csv.writer(out, lineterminator="\r\n").writerow(csv_cells(values))
    return out.getvalue()[:-2]


# -- JSON lines -------------------------------------------------------------------------------
_NON_FINITE = {math.inf: "Infinity", -math.inf: "-Infinity"}


def _strict(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return _NON_FINITE.get(value, "NaN")
    if isinstance(value, dict):
        return {k: _strict(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_strict(v) for v in value]
    return value


def json_line(obj: Any) -> str:
    """One line of JSON: ASCII only (``\\uXXXX`` escapes, so a lone surrogate is an escape, not
    invalid UTF-8), strict (NaN and infinities as the strings ``"NaN"``, ``"Infinity"``,
    ``"-Infinity"``), values JSON lacks as their ``str``."""
    return json.dumps(_strict(obj), ensure_ascii=True, allow_nan=False, default=str)


# -- ROS names --------------------------------------------------------------------------------
#: A name token valid in ROS 1 and ROS 2: a letter, then letters and digits, single underscores
#: between them (ROS 2 forbids ``__`` and a trailing ``_``).
ROS_TOKEN = re.compile(r"[A-Za-z][A-Za-z0-9]*(?:_[A-Za-z0-9]+)*")
#: How an encoded name starts (ids starting with it are encoded too).
ROS_MARK = "x0"
_ALNUM = frozenset(b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789")
_ENCODED = re.compile(r"(?:[A-Za-z0-9]|_[0-9a-f]{2})*")


def ros_name(name: str) -> str:
    """``name`` (an id) as one ROS name token (:data:`ROS_TOKEN`), by one injective rule: a
    token not starting with ``x0`` is itself; any other id is ``x0`` then its ASCII letters and
    digits, every other byte of its UTF-8 as ``_`` and two lower-case hex digits
    (``a b`` → ``x0a_20b``, ``alice-1`` → ``x0alice_2d1``, ``""`` → ``x0``); :func:`ros_id`
    reads it back."""
    if ROS_TOKEN.fullmatch(name) and not name.startswith(ROS_MARK):
        return name
    data = name.encode("utf-8", "surrogatepass")
    return ROS_MARK + "".join(chr(b) if b in _ALNUM else f"_{b:02x}" for b in data)


def ros_id(name: str) -> str:
    """The id whose :func:`ros_name` is ``name``."""
    if not name.startswith(ROS_MARK):
        return name
    body = name[len(ROS_MARK) :]
    if not _ENCODED.fullmatch(body):
        msg = f"{name!r} is not a name made by toaster.quoting.ros_name"
        raise InvalidInputError(msg)
    data = re.sub(r"_([0-9a-f]{2})", lambda m: chr(int(m.group(1), 16)), body)
    return data.encode("latin-1").decode("utf-8", "surrogatepass")
