"""The world model (entities, joints, history) and its sources (scenarios, tracks, live)."""

from toaster.world.geometry import bearing, wrap_angle
from toaster.world.history import History
from toaster.world.live import LiveSource
from toaster.world.scenario import Scenario, ScenarioSource, load_scenario, parse_scenario
from toaster.world.state import Observation, World
from toaster.world.tracks import TrackSource, read_obsmat, read_tracks

__all__ = [
    "History",
    "LiveSource",
    "Observation",
    "Scenario",
    "ScenarioSource",
    "TrackSource",
    "World",
    "bearing",
    "load_scenario",
    "parse_scenario",
    "read_obsmat",
    "read_tracks",
    "wrap_angle",
]
