"""The one list of built-in producers builds what its names say, the spatial ones on demand."""

from __future__ import annotations

from toaster.producers.registry import BUILTINS, NAMES, builtin_producers
from toaster.world.config import make_config


def test_each_builtin_is_the_producer_its_name_says() -> None:
    every = builtin_producers(make_config({}), {}, spatial=True)
    assert [p.name for p in every] == list(NAMES)
    assert NAMES == ("pdg", "area_manager", "agent_monitor", "move3d_facts")  # the original's


def test_spatial_producers_only_when_asked() -> None:
    plain = builtin_producers(make_config({}), {}, spatial=False)
    assert [p.name for p in plain] == [b.name for b in BUILTINS if b.wanted == "always"]
    assert "move3d_facts" not in [p.name for p in plain]
