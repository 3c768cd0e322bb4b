"""A new PostgreSQL schema at head in one script: the migrations' final state, not their steps.

Migrating an empty schema runs 19 revisions (~280 statements, tables and triggers made and
replaced on the way) and Alembic's Python around them. Their end result is a few dozen tables,
indexes, functions, views and triggers plus two rows: :func:`generate` writes it as one script
from the catalogue of a schema the migrations just made (inside their transaction, before
anyone else sees it), and :func:`apply` runs that script as one batch in a new, bare schema.

The script is kept per *key*: the toaster version, head and migrations hash of
:mod:`toaster.db.template` and the server's major version (the catalogue's text is the
server's). It lives beside the SQLite templates (``postgresql-<key>.sql``, written aside and
renamed) and in memory for the process. :func:`generate` refuses a schema holding anything it
does not know how to write again (privileges, comments, rules, row security, types...): the
migrations then stay the only way, as they are for every existing database. A script that
fails is rolled back to its savepoint and the caller migrates; the migrations' success then
replaces it.
"""

from __future__ import annotations

import contextlib
import os
import re
from graphlib import TopologicalSorter
from pathlib import Path
from typing import Any

from sqlalchemy import Connection

from toaster.db import template
from toaster.db.engine import database_error, dbapi, describe, lock_timeout

_TRAILER = "-- end of toaster final state\n"
_SAVEPOINT = "toaster_final_state"
_memo: dict[tuple[Path, str], str] = {}
_failed: set[tuple[Path, str]] = set()  # scripts that failed in this process

#: The schema of the statements below: the migrating connection's current one.
_NS = "(SELECT oid FROM pg_namespace WHERE nspname = current_schema())"

#: Anything in the schema beyond what :func:`generate` writes again (one row per finding).
_UNSUPPORTED = f"""
SELECT 'relation ' || relname FROM pg_class WHERE relnamespace = {_NS}
  AND (relkind NOT IN ('r', 'v', 'S', 'i') OR relacl IS NOT NULL OR relrowsecurity
       OR relforcerowsecurity OR (relkind = 'r' AND relreplident <> 'd') OR relispartition)
UNION ALL SELECT 'function ' || proname FROM pg_proc WHERE pronamespace = {_NS}
  AND (prokind NOT IN ('f', 'p') OR proacl IS NOT NULL)
UNION ALL SELECT 'column ' || a.attname FROM pg_attribute a
  JOIN pg_class c ON c.oid = a.attrelid JOIN pg_type t ON t.oid = a.atttypid
  WHERE c.relnamespace = {_NS} AND c.relkind IN ('r', 'v') AND a.attnum > 0
  AND NOT a.attisdropped AND (a.attidentity <> '' OR a.attacl IS NOT NULL
       OR a.attstattarget <> -1 OR a.attstorage <> t.typstorage
       OR a.attcollation <> t.typcollation)
UNION ALL SELECT 'constraint ' || conname FROM pg_constraint WHERE connamespace = {_NS}
  AND (conrelid = 0 OR contype NOT IN ('p', 'u', 'c', 'x', 'f') OR NOT convalidated)
UNION ALL SELECT 'rule ' || r.rulename FROM pg_rewrite r JOIN pg_class c ON c.oid = r.ev_class
  WHERE c.relnamespace = {_NS} AND r.rulename <> '_RETURN'
UNION ALL SELECT 'policy ' || p.polname FROM pg_policy p JOIN pg_class c ON c.oid = p.polrelid
  WHERE c.relnamespace = {_NS}
UNION ALL SELECT 'inheritance ' || c.relname FROM pg_inherits i
  JOIN pg_class c ON c.oid = i.inhrelid WHERE c.relnamespace = {_NS}
UNION ALL SELECT 'comment' FROM pg_description d WHERE d.objoid IN (
  SELECT oid FROM pg_class WHERE relnamespace = {_NS}
  UNION ALL SELECT oid FROM pg_proc WHERE pronamespace = {_NS})
UNION ALL SELECT 'type ' || t.typname FROM pg_type t WHERE t.typnamespace = {_NS}
  AND NOT EXISTS (SELECT 1 FROM pg_class c WHERE c.oid = t.typrelid AND c.relkind <> 'c')
  AND NOT EXISTS (SELECT 1 FROM pg_type e JOIN pg_class c ON c.oid = e.typrelid
                  WHERE e.oid = t.typelem AND t.typcategory = 'A' AND c.relkind <> 'c')
UNION ALL SELECT 'statistics ' || stxname FROM pg_statistic_ext WHERE stxnamespace = {_NS}
UNION ALL SELECT 'operator ' || oprname FROM pg_operator WHERE oprnamespace = {_NS}
UNION ALL SELECT 'collation ' || collname FROM pg_collation WHERE collnamespace = {_NS}
UNION ALL SELECT 'index ' || c.relname FROM pg_index i JOIN pg_class c ON c.oid = i.indexrelid
  WHERE c.relnamespace = {_NS} AND (i.indisclustered OR NOT i.indisvalid)
"""

_BARE = f"""
SELECT NOT EXISTS (SELECT 1 FROM pg_class WHERE relnamespace = {_NS})
   AND NOT EXISTS (SELECT 1 FROM pg_proc WHERE pronamespace = {_NS})
   AND NOT EXISTS (SELECT 1 FROM pg_type WHERE typnamespace = {_NS}),
       current_setting('server_version_num')
"""

_SEQUENCES = f"""
SELECT format('CREATE SEQUENCE %I AS %s INCREMENT BY %s MINVALUE %s MAXVALUE %s START WITH %s '
              'CACHE %s%s', c.relname, format_type(s.seqtypid, NULL), s.seqincrement,
              s.seqmin, s.seqmax, s.seqstart, s.seqcache,
              CASE WHEN s.seqcycle THEN ' CYCLE' ELSE '' END),
       format('%I', c.relname), s.seqstart,
       (SELECT format('ALTER SEQUENCE %I OWNED BY %I.%I', c.relname, o.relname, a.attname)
          FROM pg_depend d JOIN pg_class o ON o.oid = d.refobjid
          JOIN pg_attribute a ON a.attrelid = d.refobjid AND a.attnum = d.refobjsubid
         WHERE d.classid = 'pg_class'::regclass AND d.objid = c.oid
           AND d.refclassid = 'pg_class'::regclass AND d.deptype = 'a')
  FROM pg_class c JOIN pg_sequence s ON s.seqrelid = c.oid
 WHERE c.relnamespace = {_NS} ORDER BY c.oid
"""

_COLUMNS = """
SELECT string_agg(format('%I %s', a.attname, format_type(a.atttypid, a.atttypmod))
         || CASE WHEN a.attgenerated = 's'
                 THEN ' GENERATED ALWAYS AS (' || pg_get_expr(d.adbin, d.adrelid) || ') STORED'
                 WHEN d.adbin IS NOT NULL THEN ' DEFAULT ' || pg_get_expr(d.adbin, d.adrelid)
                 ELSE '' END
         || CASE WHEN a.attnotnull THEN ' NOT NULL' ELSE '' END, ', ' ORDER BY a.attnum)
  FROM pg_attribute a LEFT JOIN pg_attrdef d ON d.adrelid = a.attrelid AND d.adnum = a.attnum
 WHERE a.attrelid = c.oid AND a.attnum > 0 AND NOT a.attisdropped
"""

_TABLES = f"""
SELECT format('CREATE %sTABLE %I (%s)%s', CASE WHEN c.relpersistence = 'u' THEN 'UNLOGGED '
              ELSE '' END, c.relname, concat_ws(', ', ({_COLUMNS}),
              (SELECT string_agg(format('CONSTRAINT %I %s', co.conname,
                                        pg_get_constraintdef(co.oid)), ', ' ORDER BY co.oid)
                 FROM pg_constraint co
                WHERE co.conrelid = c.oid AND co.contype IN ('p', 'u', 'c', 'x'))),
              CASE WHEN c.reloptions IS NULL THEN ''
                   ELSE ' WITH (' || array_to_string(c.reloptions, ', ') || ')' END),
       format('%I', c.relname),
       (SELECT string_agg(format('%I', a.attname), ', ' ORDER BY a.attnum) FROM pg_attribute a
         WHERE a.attrelid = c.oid AND a.attnum > 0 AND NOT a.attisdropped
           AND a.attgenerated = '')
  FROM pg_class c WHERE c.relnamespace = {_NS} AND c.relkind = 'r' ORDER BY c.oid
"""

_FUNCTIONS = f"SELECT pg_get_functiondef(oid) FROM pg_proc WHERE pronamespace = {_NS} ORDER BY oid"

_INDEXES = f"""
SELECT pg_get_indexdef(i.indexrelid) FROM pg_index i JOIN pg_class c ON c.oid = i.indexrelid
 WHERE c.relnamespace = {_NS} AND NOT EXISTS (
       SELECT 1 FROM pg_constraint co WHERE co.conindid = i.indexrelid
          AND co.conrelid = i.indrelid AND co.contype IN ('p', 'u', 'x'))
 ORDER BY c.oid
"""

_FOREIGN_KEYS = f"""
SELECT format('ALTER TABLE %I ADD CONSTRAINT %I %s', c.relname, co.conname,
              pg_get_constraintdef(co.oid))
  FROM pg_constraint co JOIN pg_class c ON c.oid = co.conrelid
 WHERE c.relnamespace = {_NS} AND co.contype = 'f' ORDER BY co.oid
"""

_VIEWS = f"""
SELECT c.oid, format('CREATE VIEW %I%s AS %s', c.relname,
              CASE WHEN c.reloptions IS NULL THEN ''
                   ELSE ' WITH (' || array_to_string(c.reloptions, ', ') || ')' END,
              rtrim(pg_get_viewdef(c.oid), ';')),
       ARRAY(SELECT DISTINCT d.refobjid FROM pg_rewrite r JOIN pg_depend d
                ON d.classid = 'pg_rewrite'::regclass AND d.objid = r.oid
               AND d.refclassid = 'pg_class'::regclass
             WHERE r.ev_class = c.oid AND d.refobjid <> c.oid),
       (SELECT string_agg(format('ALTER VIEW %I ALTER COLUMN %I SET DEFAULT %s', c.relname,
                                 a.attname, pg_get_expr(d.adbin, d.adrelid)), ';\n')
          FROM pg_attrdef d JOIN pg_attribute a ON a.attrelid = d.adrelid AND a.attnum = d.adnum
         WHERE d.adrelid = c.oid)
  FROM pg_class c WHERE c.relnamespace = {_NS} AND c.relkind = 'v' ORDER BY c.oid
"""

_TRIGGERS = f"""
SELECT pg_get_triggerdef(t.oid, true),
       CASE t.tgenabled WHEN 'O' THEN NULL
            ELSE format('ALTER TABLE %I %s TRIGGER %I', c.relname,
                        CASE t.tgenabled WHEN 'D' THEN 'DISABLE' WHEN 'R' THEN 'ENABLE REPLICA'
                             ELSE 'ENABLE ALWAYS' END, t.tgname) END
  FROM pg_trigger t JOIN pg_class c ON c.oid = t.tgrelid
 WHERE c.relnamespace = {_NS} AND NOT t.tgisinternal ORDER BY t.oid
"""


def bare_key(conn: Connection, head: str) -> str | None:
    """The script's key when the current schema holds no relation, function or type (a new
    schema), else None: :func:`toaster.db.template.template_key` and the server's major
    version (one round trip)."""
    bare, version = conn.exec_driver_sql(_BARE).one()
    return f"{template.template_key(head)}-pg{int(version) // 10000}" if bare else None


def generate(conn: Connection) -> str | None:
    """The script that makes the current schema again in a bare schema (objects and rows),
    or None when it holds something the script would not make (see module)."""
    if conn.exec_driver_sql(_UNSUPPORTED + " LIMIT 1").first() is not None:
        return None
    path, schema = conn.exec_driver_sql(
        "SELECT current_setting('search_path'), quote_ident(current_schema())"
    ).one()
    cur: Any = dbapi(conn).cursor()  # raw: the catalogue's text holds '%'
    # Only this schema on the path: the catalogue's text names its objects unqualified.
    cur.execute("SELECT set_config('search_path', %s, true)", (schema,))
    try:
        statements = _statements(cur, schema)
    finally:
        cur.execute("SELECT set_config('search_path', %s, true)", (path,))
    if statements is None:
        return None
    return "".join(f"{statement};\n" for statement in statements) + _TRAILER


def _statements(cur: Any, schema: str) -> list[str] | None:
    out = ["SET LOCAL check_function_bodies = off"]  # as pg_dump: bodies may name later objects
    sequences = cur.execute(_SEQUENCES).fetchall()
    out += [create for create, *_ in sequences]
    tables = cur.execute(_TABLES).fetchall()
    out += [create for create, *_ in tables]
    out += [owned for *_, owned in sequences if owned]
    for sql in _rows(cur, _FUNCTIONS):  # after the tables: a signature may name a row type
        header = re.match(rf"CREATE OR REPLACE (FUNCTION|PROCEDURE) {re.escape(schema)}\.", sql)
        if header is None:
            return None
        out.append(f"CREATE {header.group(1)} {sql[header.end() :]}")
    for _, name, columns in tables:
        cur.execute(f"SELECT quote_literal(json_agg(t)::text) FROM {name} t")
        (rows,) = cur.fetchone()
        if rows is not None:
            out.append(
                f"INSERT INTO {name} ({columns}) SELECT {columns} FROM "
                f"json_populate_recordset(NULL::{name}, {rows})"
            )
    for _, name, start, _ in sequences:
        cur.execute(f"SELECT last_value, is_called FROM {name}")
        last, called = cur.fetchone()
        if called or last != start:
            quoted = "'" + name.replace("'", "''") + "'"
            out.append(f"SELECT setval({quoted}, {int(last)}, {bool(called)})")
    for sql in _rows(cur, _INDEXES):
        found = re.match(rf"(CREATE (?:UNIQUE )?INDEX \S+ ON ){re.escape(schema)}\.", sql)
        if found is None:
            return None
        out.append(found.group(1) + sql[found.end() :])
    out += _rows(cur, _FOREIGN_KEYS)
    views = {oid: (create, deps, defaults) for oid, create, deps, defaults in cur.execute(_VIEWS)}
    order = TopologicalSorter(
        {oid: [d for d in deps if d in views] for oid, (_, deps, _) in views.items()}
    )
    for oid in order.static_order():
        create, _, defaults = views[oid]
        out += [create, *([defaults] if defaults else [])]
    for create, enable in cur.execute(_TRIGGERS).fetchall():
        out += [create, *([enable] if enable else [])]
    return out


def _rows(cur: Any, sql: str) -> list[str]:
    return [row[0] for row in cur.execute(sql).fetchall()]


def _path(name: str) -> Path:
    return template.cache_folder() / f"postgresql-{name}.sql"


def script(name: str) -> str | None:
    """The script of key ``name`` (memory, then the cache folder), None when there is none."""
    memo = (template.cache_folder(), name)
    if memo not in _memo:
        try:
            text = _path(name).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError):
            return None
        if not text.endswith(_TRAILER):  # damaged: made again by the next migration
            return None
        _memo[memo] = text
    return _memo[memo]


def save(conn: Connection, name: str) -> None:
    """Generate the script of the schema ``conn`` just migrated and keep it under ``name``
    (in memory; in the cache folder unless it cannot be written), unless a good one is kept
    already (one that failed in this process is made again)."""
    memo = (template.cache_folder(), name)
    if memo not in _failed and script(name) is not None:
        return
    text = generate(conn)
    _failed.discard(memo)
    if text is None:
        forget(name)
        return
    _memo[memo] = text
    path = _path(name)
    temp = path.with_name(f".{path.name}.tmp-{os.getpid()}-{os.urandom(4).hex()}")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        temp.write_text(text, encoding="utf-8")
        os.replace(temp, path)
    except OSError:  # a read-only or full cache: this process keeps it in memory
        with contextlib.suppress(OSError):
            temp.unlink(missing_ok=True)


def forget(name: str) -> None:
    """Drop the script of ``name``, from memory and from the cache folder."""
    _memo.pop((template.cache_folder(), name), None)
    with contextlib.suppress(OSError):
        _path(name).unlink(missing_ok=True)


def apply(conn: Connection, name: str) -> bool:
    """Make the current (bare) schema with the script of ``name``, in a savepoint of
    ``conn``'s transaction (one round trip); False when there is none or it failed (rolled
    back to the savepoint). A failed script is replaced by the next :func:`save` (after the
    migrations succeed where it failed: a role that may not create tables fails both, and
    keeps it)."""
    text = script(name)
    if text is None:
        return False
    import psycopg

    cur = dbapi(conn).cursor()
    try:  # no parameters: one batch in the simple query protocol, no placeholders read
        cur.execute(f"SAVEPOINT {_SAVEPOINT};\n{text}RELEASE SAVEPOINT {_SAVEPOINT}")
    except psycopg.Error as exc:
        error = database_error(exc, describe(conn.engine.url), lock_timeout())
        if error is not None:  # the user's to fix (a lost server, a lock held too long)
            raise error from None
        cur.execute(f"ROLLBACK TO SAVEPOINT {_SAVEPOINT}")
        _failed.add((template.cache_folder(), name))
        return False
    return True
