"""Decode once: frames into periods (the plant's SYNCs), PDO columns by the layout the SDO transfers on the bus set
up, the SDO log. Every consumer of frames (a run, a replay, the CiA 402 master's record) uses this Decoder."""
