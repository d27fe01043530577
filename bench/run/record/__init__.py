"""Frames as numpy chunks (FRAME_DTYPE): the sources a run's frames come from (libhil's recorder, candump's log, a
python-can listener) and the bus.log files written and read in candump's format."""
