"""Throw-away PostgreSQL clusters for tests of replication (tests/db/test_replicas.py).

Each :class:`Cluster` is a data folder of its own, made with this machine's server binaries
(``initdb``, ``pg_ctl``, ``pg_basebackup``: ``$TOASTER_TEST_PG_BINDIR``, else ``pg_config
--bindir``, else the newest ``/usr/lib/postgresql/*/bin``), listening on 127.0.0.1 at a free
port and on a socket in its own folder, trusting local connections, stopped and removed
afterwards. The shared server (127.0.0.1:5432) is never touched. As root the binaries run as
the ``postgres`` OS user (the server refuses to run as root), in a folder that user owns.

:func:`require_clusters` is the gate: a missing binary or user skips the test with the reason
on a newcomer's machine and fails it under CI (``CI`` or ``TOASTER_REQUIRE_POSTGRES=1``).
"""

from __future__ import annotations

import os
import pwd
import shutil
import socket
import subprocess
import tempfile
import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path

import pytest
import sqlalchemy as sa

from toaster.db.engine import make_engine

#: Generous: a loaded machine starts, copies and replays slower, never differently.
TIMEOUT_S = 120.0
SERVER_USER = "postgres"
#: Settings of every throw-away cluster: small, no fsync (nothing to keep), TCP on 127.0.0.1.
BASE_SETTINGS = {
    "listen_addresses": "'127.0.0.1'",
    "fsync": "off",
    "shared_buffers": "'16MB'",
    "max_connections": "30",
    "max_wal_senders": "10",
    "max_replication_slots": "10",
    "hot_standby": "on",
    "logging_collector": "off",
}


def bindir() -> Path | None:
    """The folder of the server binaries, or None when this machine has none."""
    env = os.environ.get("TOASTER_TEST_PG_BINDIR")
    if env:
        return Path(env)
    pg_config = shutil.which("pg_config")
    if pg_config:
        out = subprocess.run([pg_config, "--bindir"], capture_output=True, text=True, check=False)
        folder = Path(out.stdout.strip())
        if out.returncode == 0 and (folder / "initdb").exists():
            return folder
    found = sorted(
        Path("/usr/lib/postgresql").glob("*/bin/initdb"), key=lambda p: int(p.parent.parent.name)
    )
    return found[-1].parent if found else None


def _unavailable() -> str | None:
    """Why throw-away clusters cannot be made here, or None."""
    folder = bindir()
    if folder is None:
        return "no PostgreSQL server binaries (initdb) found: set TOASTER_TEST_PG_BINDIR"
    for name in ("initdb", "pg_ctl", "pg_basebackup"):
        if not (folder / name).exists():
            return f"{folder / name} is missing"
    if os.geteuid() == 0:
        try:
            pwd.getpwnam(SERVER_USER)
        except KeyError:
            return f"running as root and there is no {SERVER_USER!r} OS user to run the server"
        if shutil.which("runuser") is None:
            return "running as root and runuser (to run the server as postgres) is missing"
    return None


def require_clusters() -> None:
    """Skip (newcomer) or fail (CI) when throw-away clusters cannot be made."""
    reason = _unavailable()
    if reason is None:
        return
    if os.environ.get("CI") or os.environ.get("TOASTER_REQUIRE_POSTGRES") == "1":
        pytest.fail(f"cannot start throw-away PostgreSQL clusters: {reason} (CI requires them)")
    pytest.skip(f"cannot start throw-away PostgreSQL clusters: {reason}")


def free_port() -> int:
    """A TCP port of 127.0.0.1 free now (the kernel's pick)."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _as_server(args: list[str]) -> list[str]:
    return ["runuser", "-u", SERVER_USER, "--", *args] if os.geteuid() == 0 else args


def run(args: list[str]) -> str:
    """Run a server binary (as ``postgres`` when root); its output, or an error with it."""
    out = subprocess.run(_as_server(args), capture_output=True, text=True, check=False)
    if out.returncode != 0:
        msg = f"{' '.join(args)} failed ({out.returncode}): {out.stdout}{out.stderr}"
        raise RuntimeError(msg)
    return out.stdout


class Cluster:
    """One throw-away cluster in ``root/name`` (superuser ``postgres``, trust)."""

    def __init__(self, root: Path, name: str) -> None:
        self.root = root
        self.name = name
        self.data = root / name
        self.port = 0
        self.running = False

    def url(self, dbname: str = "postgres") -> str:
        return f"postgresql://postgres@127.0.0.1:{self.port}/{dbname}"

    def _bin(self, name: str) -> str:
        folder = bindir()
        assert folder is not None
        return str(folder / name)

    def init(self, **settings: str) -> Cluster:
        """initdb, then the settings (:data:`BASE_SETTINGS` and ``settings``) appended."""
        run([self._bin("initdb"), "-D", str(self.data), "-U", "postgres", "--auth=trust", "-E",
             "UTF8", "--locale=C", "--no-sync"])  # fmt: skip
        self.configure(**settings)
        return self

    def configure(self, **settings: str) -> None:
        """Append settings to postgresql.conf (later lines win); a new port each time."""
        self.port = free_port()
        lines = {**BASE_SETTINGS, **settings, "port": str(self.port)}
        lines["unix_socket_directories"] = f"'{self.root}'"
        text = "".join(f"{key} = {value}\n" for key, value in lines.items())
        conf = self.data / "postgresql.conf"
        # The file belongs to the server's user: append through it.
        run(["sh", "-c", f"cat >> {conf} <<'EOF'\n{text}EOF"])

    def start(self) -> Cluster:
        run([self._bin("pg_ctl"), "-D", str(self.data), "-l", str(self.root / f"{self.name}.log"),
             "-w", "-t", str(int(TIMEOUT_S)), "start"])  # fmt: skip
        self.running = True
        return self

    def stop(self) -> None:
        if self.running:
            self.running = False
            run([self._bin("pg_ctl"), "-D", str(self.data), "-m", "immediate", "-w", "stop"])

    def standby_into(self, replica: Cluster) -> Cluster:
        """``replica`` made a hot standby of this (running) cluster: ``pg_basebackup -R``
        (streaming the WAL it needs, then following this one), started."""
        run([self._bin("pg_basebackup"), "-h", "127.0.0.1", "-p", str(self.port), "-U",
             "postgres", "-D", str(replica.data), "-R", "-X", "stream", "--no-sync"])  # fmt: skip
        replica.configure()
        return replica.start()

    def log(self) -> str:
        path = self.root / f"{self.name}.log"
        return path.read_text(errors="replace") if path.exists() else ""

    def execute(self, sql: str, dbname: str = "postgres", *, autocommit: bool = False) -> None:
        """Run ``sql`` (autocommit: outside a transaction, e.g. CREATE DATABASE)."""
        engine = make_engine(self.url(dbname))
        try:
            if autocommit:
                with engine.connect().execution_options(isolation_level="AUTOCOMMIT") as conn:
                    conn.exec_driver_sql(sql)
            else:
                with engine.begin() as conn:
                    conn.exec_driver_sql(sql)
        finally:
            engine.dispose()

    def scalar(self, sql: str, dbname: str = "postgres", **params: object) -> object:
        engine = make_engine(self.url(dbname))
        try:
            with engine.connect() as conn:
                return conn.execute(sa.text(sql), params).scalar()
        finally:
            engine.dispose()

    def wait_for(self, sql: str, dbname: str = "postgres", **params: object) -> None:
        """Poll until ``sql`` gives true (a condition, never a duration); fails with the log
        after :data:`TIMEOUT_S`."""
        deadline = time.monotonic() + TIMEOUT_S
        while not self.scalar(sql, dbname, **params):
            if time.monotonic() > deadline:
                pytest.fail(f"{self.name}: no {sql!r} after {TIMEOUT_S} s\n{self.log()[-3000:]}")
            time.sleep(0.05)


class Clusters:
    """The clusters of one test: made in one folder, each stopped when the test ends."""

    def __init__(self, root: Path, stack: ExitStack) -> None:
        self.root = root
        self._stack = stack

    def new(self, name: str, **settings: str) -> Cluster:
        """A new cluster with ``settings``, started."""
        cluster = Cluster(self.root, name)
        self._stack.callback(cluster.stop)
        return cluster.init(**settings).start()

    def standby(self, primary: Cluster, name: str) -> Cluster:
        """A hot standby of ``primary``, started."""
        replica = Cluster(self.root, name)
        self._stack.callback(replica.stop)
        return primary.standby_into(replica)


@contextmanager
def clusters() -> Iterator[Clusters]:
    """Throw-away clusters in a folder owned by the server's user, all stopped and removed
    afterwards, whatever happened."""
    require_clusters()
    root = Path(tempfile.mkdtemp(prefix="toaster-replicas-"))
    try:
        if os.geteuid() == 0:
            entry = pwd.getpwnam(SERVER_USER)
            os.chown(root, entry.pw_uid, entry.pw_gid)
        with ExitStack() as stack:
            yield Clusters(root, stack)
    finally:
        shutil.rmtree(root, ignore_errors=True)
