"""Simulation: the compiled model kernel, its inputs and synthetic logs."""

from balancer_id.simulation.engine import Simulation, TrialInput, simulate, simulate_many
from balancer_id.simulation.inputs import Thrust, Trapezoid, parse_trajectory

__all__ = [
    "Simulation",
    "Thrust",
    "Trapezoid",
    "TrialInput",
    "parse_trajectory",
    "simulate",
    "simulate_many",
]
