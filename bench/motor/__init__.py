"""A user's motor (docs/YOUR_MOTOR.md): a folder with motor.toml and a flux-map table, read and checked (folder.py),
the flux map as the plant interpolates it and the bytes its object 0x2008 takes (fluxmap.py), the example motor
(example.py), and the plant settings a folder gives a scenario (settings.py)."""

from __future__ import annotations

from bench.motor.fluxmap import FluxMap, FluxMapProblem
from bench.motor.folder import MotorError, MotorFolder, load

__all__ = ["FluxMap", "FluxMapProblem", "MotorError", "MotorFolder", "load"]
