"""Flight: JSBSim aircraft, closed-loop autopilot, tracks as data, truth at the IMU rate."""

from navsim.flight.environment import Environment, parse_environment
from navsim.flight.simulator import FlightConfig, fly
from navsim.flight.track import Track, load_track, parse_track
from navsim.flight.truth import Pose, Truth

__all__ = ["Environment", "FlightConfig", "Pose", "Track", "Truth", "fly", "load_track", "parse_environment",
           "parse_track"]
