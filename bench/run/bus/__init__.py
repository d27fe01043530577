"""The run's bus and nodes: which bus a run uses (one BusKind per kind of bus, kind.py and kind_*.py, chosen once by
buses.choose_bus), the node processes, the in-process direct bus (libhil.so), the fault gateway, the VM that holds
SocketCAN, the CAN box, and the watch over the nodes' lives. Knows no scenario."""
