"""Every benchmark of ``benchmarks/`` runs its ``--quick`` mode (small sizes, one run) on each
backend it takes, as a subprocess, so that the benchmarks cannot rot: it must exit 0 and print
its table. Figures are not checked (a loaded machine gives any). bench_soak.py's quick run is
tests/ros1/test_bench_soak.py; bench_live.py needs ROS 1 (skip, or fail under CI, without), its
``--ros2 --foxglove`` run also toaster[ros2] and toaster[foxglove] with websockets."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import PG_URL, require_postgres
from tests.ros1.conftest import require_ros
from tests.ros2.conftest import require_cyclonedds

pytestmark = pytest.mark.slow  # every test here runs a benchmark process for seconds

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
PG = pytest.mark.postgresql

#: (script, backend or "" when it takes none, its arguments, a line of its table's header)
CASES = [
    ("bench_producers.py", "", ["--quick"], r"entities\s+areas\s+agents\s+tick ms"),
    ("bench_spatial.py", "", ["--quick"], r"10 agents x\s+100 objects: .* ms/tick median"),
    (
        "bench_store.py",
        "sqlite",
        ["--quick", "--backend", "sqlite"],
        r"measure\s+toaster\s+baseline\s+ratio",
    ),
    (
        "bench_store.py",
        "postgresql",
        ["--quick", "--backend", "postgresql", "--pg", PG_URL],
        r"measure\s+toaster\s+baseline\s+ratio",
    ),
    ("bench_beliefs.py", "sqlite", ["--quick", "--no-pg"], r"backend\s+agents\s+depth\s+rules"),
    (
        "bench_beliefs.py",
        "postgresql",
        ["--quick", "--only-pg", "--pg", PG_URL],
        r"backend\s+agents\s+depth\s+rules",
    ),
    ("bench_run.py", "sqlite", ["--quick", "--no-pg"], r"scene\s+backend\s+holders\s+no-db ms"),
    (
        "bench_run.py",
        "postgresql",
        ["--quick", "--only-pg", "--pg", PG_URL],
        r"maintenance\s+input s\s+wall s",  # its last section, PostgreSQL's long run
    ),
    ("bench_live.py", "sqlite", ["--quick", "--no-pg"], r"path\s+humans\s+backend\s+changes"),
    (
        "bench_live.py",
        "postgresql",
        ["--quick", "--only-pg", "--pg", PG_URL],
        r"path\s+humans\s+backend\s+changes",
    ),
    (
        "bench_live.py",
        "",
        ["--quick", "--no-pg", "--ros2", "--foxglove"],
        r"ROS 2 FactList / ROS 1 FactList: p50 [\d.]+x",
    ),
    ("bench_writers.py", "postgresql", ["--quick", "--pg", PG_URL], r"writers\s+database\s+p50"),
    ("bench_fresh.py", "sqlite", ["--quick", "--no-pg"], r"measure\s+backend\s+fresh ms"),
    (
        "bench_fresh.py",
        "postgresql",
        ["--quick", "--only-pg", "--pg", PG_URL],
        r"measure\s+backend\s+fresh ms",
    ),
    ("soak_writers.py", "sqlite", ["--quick", "--db", "sqlite"], r"total: \d+ ticks, 0 failed"),
    ("soak_writers.py", "postgresql", ["--quick", "--db", PG_URL], r"total: \d+ ticks, 0 failed"),
]


@pytest.mark.parametrize(
    ("script", "backend", "args", "header"),
    [
        pytest.param(
            *case,
            id=f"{case[0]}-{case[1] or 'nodb'}",
            marks=[PG] if case[1] == "postgresql" else [],
        )
        for case in CASES
    ],
)
def test_quick_run_prints_its_table(
    script: str, backend: str, args: list[str], header: str
) -> None:
    if script == "bench_live.py":
        require_ros()
    if "--ros2" in args:
        require_cyclonedds()
        pytest.importorskip("foxglove")
        pytest.importorskip("websockets")
    if backend == "postgresql":
        require_postgres()
    env = os.environ | {
        "PYTHONPATH": os.pathsep.join(
            [str(BENCHMARKS.parent / "src"), os.environ.get("PYTHONPATH", "")]
        )
    }
    done = subprocess.run(
        [sys.executable, str(BENCHMARKS / script), *args],
        capture_output=True,
        text=True,
        timeout=900,
        cwd=BENCHMARKS,
        env=env,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert re.search(header, done.stdout), done.stdout[-3000:]
    if backend:  # a row of the backend asked for, none of the other
        other = "postgresql" if backend == "sqlite" else "sqlite"
        if script not in ("bench_writers.py", "soak_writers.py"):
            assert backend in done.stdout, done.stdout[-3000:]
            assert f" {other} " not in done.stdout, done.stdout[-3000:]


SCRIPTS = sorted(p.name for p in BENCHMARKS.glob("*.py") if p.name.startswith(("bench_", "soak_")))


def test_every_benchmark_has_a_quick_run_here() -> None:
    quick = {case[0] for case in CASES} | {"bench_soak.py"}  # soak: tests/ros1/test_bench_soak.py
    assert set(SCRIPTS) <= quick, set(SCRIPTS) - quick


@pytest.mark.parametrize("script", SCRIPTS)
def test_help_describes_the_options_and_runs_nothing(script: str) -> None:
    done = subprocess.run(
        [sys.executable, str(BENCHMARKS / script), "--help"],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=BENCHMARKS,
        env=os.environ | {"PYTHONPATH": str(BENCHMARKS.parent / "src")},
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.startswith("usage: "), done.stdout[:500]
    assert "--quick" in done.stdout
