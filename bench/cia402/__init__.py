"""The bench as a CiA 402 master for drives it did not build (`bench run --drive-profile cia402`).

No plant node, no lockstep: the bench paces SYNC in real time with CAN_BCM periodic tasks, walks
the drive to OPERATION ENABLED with `canopen.BaseNode402`, plays the scenario's iq reference
profile as cyclic synchronous torque (CST, mode 10) targets, records every frame and decodes the
log once into a per-SYNC trace.
"""

NO_LOCKSTEP = "no lockstep: SYNC paced in real time by the bench"
