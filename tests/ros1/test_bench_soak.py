"""benchmarks/bench_soak.py --quick runs the soak's whole path (roscore, `toaster serve --ros1`
with status lines, the rospy client) on each backend and prints its windows and summary, so
that the benchmark cannot rot."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import PG_URL, require_postgres
from tests.ros1.conftest import require_ros

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

BENCH = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_soak.py"


@pytest.mark.parametrize(
    "backend", ["sqlite", pytest.param("postgresql", marks=pytest.mark.postgresql)]
)
def test_quick_soak_prints_windows_and_summary(backend: str) -> None:
    require_ros()
    if backend == "postgresql":
        require_postgres()
    which = ["--only-pg", "--pg", PG_URL] if backend == "postgresql" else ["--no-pg"]
    env = os.environ | {
        "PYTHONPATH": os.pathsep.join(
            [str(BENCH.parents[1] / "src"), os.environ.get("PYTHONPATH", "")]
        )
    }
    done = subprocess.run(
        [sys.executable, str(BENCH), "--quick", *which],
        capture_output=True,
        text=True,
        timeout=900,
        cwd=BENCH.parent,
        env=env,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    rows = [line.split() for line in done.stdout.splitlines() if line.startswith(backend)]
    windows, summary = rows[:-1], rows[-1]
    assert len(windows) >= 3, done.stdout  # a 10 s window for a minute of input
    assert all(float(w[2]) > 0 and float(w[7]) > 0 for w in windows), done.stdout  # ticks, RSS
    numbers = [float(value) for value in summary[1:11]]
    rss_slope, growth, rows, worst = numbers[0], numbers[3], numbers[4], numbers[6]
    assert not any(math.isnan(x) for x in (rss_slope, growth, rows, worst)), done.stdout
    assert rows > 0 and worst > 0, done.stdout
    # each target named with its verdict (met or MISSED: a loaded machine may miss them)
    assert summary[11::2] == ["RSS", "growth", "stalls"], done.stdout
