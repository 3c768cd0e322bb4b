"""The statement check: a tokenizer that reads SQL as PostgreSQL or SQLite does, and the
refusal of anything but one read statement naming no function with side effects."""

from __future__ import annotations

import re
from typing import NamedTuple

from toaster.errors import ReadOnlyError, ToasterError


class Token(NamedTuple):
    """``kind``: word (unquoted name or keyword), ident (quoted), string, number, param,
    op or semi; ``text`` as written, at ``start``."""

    kind: str
    text: str
    start: int

    @property
    def name(self) -> str:
        """A word lower-cased, a quoted identifier without its quotes (lower-cased too)."""
        if self.kind == "ident":
            quote = self.text[0]
            return self.text[1:-1].replace(quote * 2, quote).lower()
        return self.text.lower()


_IDENT = r"A-Za-z_\x80-\U0010ffff"
_WORD = re.compile(rf"[{_IDENT}][{_IDENT}0-9$]*")
_NUMBER = re.compile(r"(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_DOLLAR = re.compile(rf"\$(?:[{_IDENT}][{_IDENT}0-9]*)?\$")
_PG_PARAM = re.compile(r"\$\d+")
_SQLITE_PARAM = re.compile(rf"(?:\?\d*|[:@$][{_IDENT}0-9]+)")


def tokenize(sql: str, dialect: str) -> list[Token]:
    """The tokens of ``sql`` as PostgreSQL (standard_conforming_strings on) or SQLite reads
    them, without spaces and comments; unterminated quotes or comments are a ToasterError."""
    pg = dialect == "postgresql"
    tokens: list[Token] = []
    i, n = 0, len(sql)
    while i < n:
        c = sql[i]
        if c in " \t\n\r\f\v":
            i += 1
        elif sql.startswith("--", i):  # to the end of the line (\r too on PostgreSQL)
            end = min(
                (e for e in (sql.find("\n", i), sql.find("\r", i) if pg else -1) if e >= 0),
                default=n,
            )
            i = end + 1
        elif sql.startswith("/*", i):
            i = _block_comment(sql, i, pg)
        elif c == "'":
            i = _quoted(sql, i, "'", tokens, "string")
        elif c == '"' or (not pg and c == "`"):
            i = _quoted(sql, i, c, tokens, "ident")
        elif not pg and c == "[":
            end = sql.find("]", i)
            if end < 0:
                _unterminated("[identifier")
            tokens.append(Token("ident", '"' + sql[i + 1 : end] + '"', i))
            i = end + 1
        elif (word := _WORD.match(sql, i)) is not None:
            i = _word(sql, word.group(), i, pg, tokens)
        elif (number := _NUMBER.match(sql, i)) is not None:
            tokens.append(Token("number", number.group(), i))
            i = number.end()
        elif pg and c == "$":
            i = _dollar(sql, i, tokens)
        elif not pg and (param := _SQLITE_PARAM.match(sql, i)) is not None:
            tokens.append(Token("param", param.group(), i))
            i = param.end()
        elif c == ";":
            tokens.append(Token("semi", c, i))
            i += 1
        else:
            op = "::" if sql.startswith("::", i) else c
            tokens.append(Token("op", op, i))
            i += len(op)
    return tokens


def _unterminated(what: str) -> None:
    msg = f"SQL error: unterminated {what} in the statement: close it"
    raise ToasterError(msg)


def _block_comment(sql: str, i: int, nested: bool) -> int:
    depth, i = 1, i + 2
    while depth:
        close = sql.find("*/", i)
        if close < 0:
            if nested:  # PostgreSQL refuses it; SQLite reads to the end
                _unterminated("/* comment")
            return len(sql)
        opened = sql.find("/*", i, close) if nested else -1
        if opened >= 0:
            depth, i = depth + 1, opened + 2
        else:
            depth, i = depth - 1, close + 2
    return i


def _quoted(
    sql: str,
    i: int,
    quote: str,
    tokens: list[Token],
    kind: str,
    backslash: bool = False,
    start: int | None = None,
) -> int:
    j = i + 1
    while True:
        end = sql.find(quote, j)
        if backslash:
            slash = sql.find("\\", j)
            if 0 <= slash < end or (end < 0 <= slash):
                j = slash + 2
                continue
        if end < 0:
            _unterminated("quote " + quote)
        if sql.startswith(quote * 2, end):
            j = end + 2
            continue
        begin = i if start is None else start
        tokens.append(Token(kind, sql[begin : end + 1], begin))
        return end + 1


def _word(sql: str, word: str, i: int, pg: bool, tokens: list[Token]) -> int:
    after = i + len(word)
    prefix = word.lower()
    if pg and prefix in ("e", "b", "x", "n") and sql.startswith("'", after):
        return _quoted(sql, after, "'", tokens, "string", backslash=prefix == "e", start=i)
    if not pg and prefix == "x" and sql.startswith("'", after):
        return _quoted(sql, after, "'", tokens, "string", start=i)
    if pg and prefix == "u" and sql.startswith("&'", after):
        return _quoted(sql, after + 1, "'", tokens, "string", start=i)
    if pg and prefix == "u" and sql.startswith('&"', after):
        msg = (
            'read-only SQL does not take U&"..." identifiers (escapes can hide a name): '
            "write the name plainly or in double quotes"
        )
        raise ReadOnlyError(msg)
    tokens.append(Token("word", word, i))
    return after


def _dollar(sql: str, i: int, tokens: list[Token]) -> int:
    if (param := _PG_PARAM.match(sql, i)) is not None:
        tokens.append(Token("param", param.group(), i))
        return param.end()
    if (tag := _DOLLAR.match(sql, i)) is None:
        tokens.append(Token("op", "$", i))
        return i + 1
    end = sql.find(tag.group(), tag.end())
    if end < 0:
        _unterminated("dollar quote " + tag.group())
    tokens.append(Token("string", sql[i : end + len(tag.group())], i))
    return end + len(tag.group())


# ---------------------------------------------------------------------------- the statement
_READS = {
    "postgresql": ("select", "with", "values", "table", "explain", "show"),
    "sqlite": ("select", "with", "values", "explain", "pragma"),
}
#: Statements that write or act (their first word): refused, --write runs them.
_ACTIONS = frozenset(
    (
        "abort",
        "alter",
        "analyze",
        "analyse",
        "attach",
        "begin",
        "call",
        "checkpoint",
        "close",
        "cluster",
        "comment",
        "commit",
        "copy",
        "create",
        "deallocate",
        "declare",
        "delete",
        "detach",
        "discard",
        "do",
        "drop",
        "end",
        "execute",
        "fetch",
        "grant",
        "import",
        "insert",
        "listen",
        "load",
        "lock",
        "merge",
        "move",
        "notify",
        "prepare",
        "reassign",
        "refresh",
        "reindex",
        "release",
        "replace",
        "reset",
        "revoke",
        "rollback",
        "savepoint",
        "security",
        "set",
        "start",
        "truncate",
        "unlisten",
        "update",
        "vacuum",
    )
)
#: Words that make a read statement write (writable CTEs, SELECT INTO, row locks).
_WRITE_WORDS = frozenset(("insert", "update", "delete", "merge", "truncate", "into"))
#: PostgreSQL functions with effects beyond the transaction or the session's own reads
#: (settings, locks, files, programs, other sessions), and those that run SQL given as text
#: (PostgreSQL 15: query_to_xml*, cursor_to_xml*, ts_stat, ts_rewrite(tsquery, text); the
#: contrib modules' dblink*, crosstab*, connectby, xpath_table), where the check cannot see.
_PG_CALLS = frozenset(
    (
        "set_config",
        "pg_notify",
        "nextval",
        "setval",
        "loread",
        "lowrite",
        "pg_read_file",
        "pg_read_binary_file",
        "pg_stat_file",
        "pg_terminate_backend",
        "pg_cancel_backend",
        "pg_reload_conf",
        "pg_rotate_logfile",
        "pg_switch_wal",
        "pg_promote",
        "pg_create_restore_point",
        "pg_backup_start",
        "pg_backup_stop",
        "pg_start_backup",
        "pg_stop_backup",
        "pg_log_backend_memory_contexts",
        "pg_logical_emit_message",
        "pg_import_system_collations",
        "query_to_xml",
        "query_to_xmlschema",
        "query_to_xml_and_xmlschema",
        "cursor_to_xml",
        "cursor_to_xmlschema",
        "ts_stat",
        "ts_rewrite",
        "pg_logical_slot_get_changes",
        "pg_logical_slot_peek_changes",
        "connectby",
        "xpath_table",
    )
)
#: Families of them (a call of a name that starts so).
_PG_CALL_PREFIXES = (
    "pg_advisory",
    "pg_try_advisory",
    "dblink",
    "lo_",
    "pg_ls_",
    "pg_file_",
    "pg_stat_reset",
    "pg_replication_",
    "pg_create_",
    "pg_drop_",
    "pg_copy_",
    "pg_wal_replay_",
    "binary_upgrade_",
    "table_to_xml",
    "schema_to_xml",
    "database_to_xml",
    "pg_logdir_",
    "crosstab",
)
#: toaster's own functions (the triggers' functions the migrations and toaster.beliefs
#: install, the read-only wrapper): no statement has a reason to call them.
_PG_OWN = "toaster_"
#: The session's temporary schemas (``pg_temp``, ``pg_temp_3``, ``pg_toast_temp_3``): they
#: hold toaster's read-only wrapper, never anything a statement may use.
_PG_TEMP = re.compile(r"pg_(?:toast_)?temp(?:_\d+)?")
#: SQLite functions that load code or touch files (the SQLite authorizer denies them too).
SQLITE_CALLS = frozenset(("load_extension", "fts3_tokenizer", "readfile", "writefile", "edit"))


def check_statement(sql: str, dialect: str) -> list[Token]:
    """The tokens of ``sql`` if it is one read statement; else a ReadOnlyError (it writes or
    acts: ``--write`` runs it) or a ToasterError (not SQL toaster reads)."""
    if "\x00" in sql:
        msg = "SQL error: the statement contains a NUL character: remove it"
        raise ToasterError(msg)
    tokens = tokenize(sql, dialect)
    while tokens and tokens[-1].kind == "semi":
        tokens.pop()
    if not tokens:
        msg = 'SQL error: the statement is empty: give one, e.g. "SELECT 1"'
        raise ToasterError(msg)
    if any(t.kind == "semi" for t in tokens):
        msg = (
            "read-only SQL runs exactly one statement (this has several): run them one at "
            "a time, or all with --write"
        )
        raise ReadOnlyError(msg)
    first = next((t for t in tokens if t.text != "("), tokens[0])
    word = first.name if first.kind == "word" else ""
    if word in _ACTIONS:
        _refuse(f"{word.upper()} statements")
    if word not in _READS[dialect]:
        reads = ", ".join(w.upper() for w in _READS[dialect])
        msg = f"SQL error: read-only SQL starts with {reads}, not {first.text[:40]!r}"
        raise ToasterError(msg)
    if word == "explain":
        _check_explain(tokens[tokens.index(first) + 1 :], dialect)
    for index, token in enumerate(tokens):
        if token.kind == "word" and token.name in _WRITE_WORDS:
            _refuse(f"{token.name.upper()} (it writes)")
        if (
            token.kind == "word"
            and token.name == "for"
            and index + 1 < len(tokens)
            and tokens[index + 1].name in ("update", "share", "no", "key")
        ):
            _refuse("row locks (FOR UPDATE / FOR SHARE)")
        if (
            dialect == "postgresql"
            and token.kind in ("word", "ident")
            and _PG_TEMP.fullmatch(token.name)
        ):
            _refuse(f"{token.name} (the session's temporary schema, toaster's own)")
        called = index + 1 < len(tokens) and tokens[index + 1].text == "("
        if (
            dialect == "postgresql"
            and called
            and token.kind in ("word", "ident")
            and token.name.startswith(_PG_OWN)
        ):
            _refuse(f"{token.name}() (toaster's own function)")
        if token.kind in ("word", "ident") and _denied_call(token.name, dialect, called):
            _refuse(f"{token.name}() (a side effect beyond the statement)")
    return tokens


def _refuse(what: str) -> None:
    msg = f"statement refused, read-only SQL does not allow {what}: rerun with --write"
    raise ReadOnlyError(msg)


def _check_explain(rest: list[Token], dialect: str) -> None:
    skip = {"analyze", "analyse", "verbose", "query", "plan"}
    index = 0
    if rest and rest[0].text == "(" and dialect == "postgresql":
        depth = 0
        for index, token in enumerate(rest):  # noqa: B007 (index is used after the loop)
            depth += {"(": 1, ")": -1}.get(token.text, 0)
            if depth == 0:
                break
        index += 1
    while index < len(rest) and rest[index].name in skip:
        index += 1
    inner = rest[index].name if index < len(rest) else ""
    if inner not in ("select", "with", "values", "table"):
        _refuse("EXPLAIN of anything but a read")


def _denied_call(name: str, dialect: str, called: bool) -> bool:
    """A denied function's name (anywhere), or a call of a denied family (``lo_…(``)."""
    if dialect == "sqlite":
        return name in SQLITE_CALLS
    return name in _PG_CALLS or (called and name.startswith(_PG_CALL_PREFIXES))


def pyformat(sql: str, tokens: list[Token]) -> str:
    """``sql`` with its ``:name`` parameters as psycopg's ``%(name)s`` (``%`` doubled
    elsewhere); ``::`` casts, slices ``a[1:n]`` and quoted text are left alone."""
    out, last = [], 0
    for index, colon in enumerate(tokens[:-1]):
        name = tokens[index + 1]
        if colon.text != ":" or name.kind != "word" or name.start != colon.start + 1:
            continue
        prev = tokens[index - 1] if index else None
        if (
            prev is not None
            and prev.start + len(prev.text) == colon.start
            and prev.kind in ("word", "number", "ident")
        ):
            continue  # a slice bound (a[1:n]), not a parameter
        out.append(sql[last : colon.start].replace("%", "%%"))
        out.append(f"%({name.text})s")
        last = name.start + len(name.text)
    out.append(sql[last:].replace("%", "%%"))
    return "".join(out)
