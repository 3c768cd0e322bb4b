"""Migrated SQLite templates: a new database file is a copy of one, not 19 migrations.

A template is a SQLite file migrated to head once per *key*: the toaster version, the head
revision and a hash of the migrations' files (revisions, frozen triggers, their loader), so a
source checkout whose revisions changed never copies a stale one. Templates live in
``$XDG_CACHE_HOME/toaster/templates/`` (default ``~/.cache/toaster/templates/``), one file
per key, named ``sqlite-<version>-<head>-<hash>.db``. Each is built in a hidden temporary file
of that folder and renamed into place: a concurrent process sees the whole file or none (two
that build at once both rename a complete file). Without a writable cache folder, a new
database is migrated in place as before. The file keeps everything the migrations set:
the schema, the seed rows, the ``alembic_version`` row and the WAL journal mode.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import shutil
from collections.abc import Callable
from functools import cache
from importlib import metadata, resources
from pathlib import Path

from toaster.errors import ToasterError

#: Environment variable of the cache root (XDG Base Directory specification).
CACHE_VAR = "XDG_CACHE_HOME"
_HEADER = b"SQLite format 3\x00"


def cache_folder() -> Path:
    """``$XDG_CACHE_HOME/toaster/templates`` (default ``~/.cache/toaster/templates``)."""
    root = os.environ.get(CACHE_VAR, "").strip()
    base = Path(root) if root and Path(root).is_absolute() else Path.home() / ".cache"
    return base / "toaster" / "templates"


@cache
def migrations_hash() -> str:
    """A hash of every file of the migrations package (revisions, frozen triggers, env)."""
    digest = hashlib.sha256()
    root = Path(str(resources.files("toaster") / "migrations"))
    for path in sorted(root.rglob("*")):
        if path.is_file() and "__pycache__" not in path.parts and path.suffix != ".pyc":
            digest.update(path.relative_to(root).as_posix().encode() + b"\0")
            digest.update(path.read_bytes() + b"\0")
    return digest.hexdigest()[:16]


@cache
def _version() -> str:
    """This toaster's installed version (read once: the metadata lookup scans the path)."""
    try:
        return metadata.version("toaster")
    except metadata.PackageNotFoundError:  # run from a source tree without installing
        return "source"


def template_key(head: str) -> str:
    """What a template depends on: this toaster's version, ``head`` and the migrations' hash."""
    return f"{_version()}-{head}-{migrations_hash()}"


def template_name(head: str) -> str:
    """The file name of the template for ``head`` and this toaster's migrations."""
    return f"sqlite-{template_key(head)}.db"


def is_whole(path: Path) -> bool:
    """True when ``path`` is a complete SQLite file whose write-ahead log is empty: the
    header's magic and page count match its size (a cheap check, no connection)."""
    try:
        size = path.stat().st_size
        with path.open("rb") as file:
            header = file.read(100)
    except OSError:
        return False
    wal = Path(f"{path}-wal")
    if len(header) < 100 or not header.startswith(_HEADER) or (wal.exists() and wal.stat().st_size):
        return False
    page_size = int.from_bytes(header[16:18], "big")
    page_size = 65536 if page_size == 1 else page_size
    pages = int.from_bytes(header[28:32], "big")
    counted = header[24:28] == header[92:96]  # the page count is valid (SQLite >= 3.7)
    return counted and pages > 0 and size == pages * page_size


def template(head: str, build: Callable[[Path], None]) -> Path | None:
    """The template for ``head``, built with ``build(temp_path)`` if missing or damaged;
    None when the cache folder cannot be written (the caller migrates instead)."""
    folder = cache_folder()
    path = folder / template_name(head)
    if is_whole(path):
        return path
    temp = folder / f".{path.name}.tmp-{os.getpid()}-{os.urandom(4).hex()}"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        _remove_orphans(folder)
        build(temp)
        os.replace(temp, path)
    except (OSError, ToasterError):  # a read-only or full cache: migrate in place instead
        return None
    finally:
        for leftover in (temp, *(Path(f"{temp}{s}") for s in ("-wal", "-shm", "-journal"))):
            with contextlib.suppress(OSError):
                leftover.unlink(missing_ok=True)
    return path if is_whole(path) else None


def _remove_orphans(folder: Path) -> None:
    """Remove the temporary files of builders that died (killed while building)."""
    for leftover in folder.glob(".*.tmp-*"):
        pid = leftover.name.rsplit(".tmp-", 1)[1].split("-", 1)[0]
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:
            leftover.unlink(missing_ok=True)
        except (ValueError, OSError):  # not ours, or a live process of another user
            continue


def copy_template(source: Path, target: Path) -> bool:
    """Copy ``source`` to ``target`` (a new file); False, copying nothing, if ``source`` is
    not whole (then the caller migrates)."""
    if not is_whole(source):
        return False
    shutil.copyfile(source, target)
    if not is_whole(target):  # the template was replaced or damaged while we copied
        target.unlink(missing_ok=True)
        return False
    return True
