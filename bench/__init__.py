"""PMSM deadbeat current control hardware-in-the-loop bench over CANopen (SocketCAN)."""

__version__ = "0.1.0"
