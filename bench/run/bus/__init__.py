"""The run's bus and nodes: which bus a run uses, the node processes, the in-process direct bus (libhil.so), the
fault gateway, the VM that holds SocketCAN, and the watch over the nodes' lives. Knows no scenario."""
