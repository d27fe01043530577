"""The CAN box: one VM, booted once, that holds what needs the kernel's CAN on a host whose kernel has none
(vcan links, the C node processes, candump, the fault gateway, can-gw) and bridges its buses to the host
over SLCAN, which python-can speaks (docs/VM.md). Every line of Python stays on the host."""
