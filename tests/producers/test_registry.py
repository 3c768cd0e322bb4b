"""The one list of built-in producers builds what its names say, the spatial ones on demand."""

from __future__ import annotations

import subprocess
import sys

from toaster.producers.registry import BUILTINS, NAMES, builtin_producers
from toaster.world.config import make_config


def test_each_builtin_is_the_producer_its_name_says() -> None:
    every = builtin_producers(make_config({}), {}, spatial=True, live=True)
    assert [p.name for p in every] == list(NAMES)
    # the original's, and IsSeen (which its documentation lists from pdg) for live nodes
    assert NAMES == ("pdg", "area_manager", "agent_monitor", "move3d_facts", "pdg_seen")


def test_spatial_producers_only_when_asked() -> None:
    plain = builtin_producers(make_config({}), {}, spatial=False)
    assert [p.name for p in plain] == [b.name for b in BUILTINS if b.wanted == "always"]
    assert "move3d_facts" not in [p.name for p in plain]
    assert "pdg_seen" not in [p.name for p in plain]  # toaster run: only a live node


def test_the_names_load_light() -> None:
    """The bridge and recordings read NAMES: no producer module, numpy or shapely comes along."""
    probe = (
        "import sys\nfrom toaster.producers.registry import NAMES\n"
        "print(' '.join(m for m in ('numpy', 'shapely', 'toaster.producers.areas') "
        "if m in sys.modules))"
    )
    done = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True, timeout=60
    )
    assert done.stdout.split() == []
