"""Decode once: frames into periods (the plant's SYNCs), PDO columns by the layout the SDO transfers on the bus set
up, the SDO log. Every consumer of frames (a run, a replay, the CiA 402 master's record) uses this Decoder: its
profile "hil" for the project's plant and drive, "cia402" for the bench as the master of a drive (no plant).
decoder.py feeds and freezes the layout, rows.py makes the rows, layout.py reads the PDOs off the SDO log
(sdo_log.py), syncs.py says which SYNCs are the loop's, counts.py holds what was counted."""
