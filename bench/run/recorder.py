"""The recorder's sources a run's bus kind names (BusKind.recorder, bench/run/bus/kind.py), made for the run's
session: candump on this host's interface or in the CAN box's slot, libhil's frames, or a listener on the master's
own bus (bench/run/record/sources.py)."""

from __future__ import annotations

from bench.run.bus.kind import FrameSource
from bench.run.loop.session import Session


class RunRecorders:
    """bench.run.bus.kind.Recorders for one run's session (its options, its links, its box lease, its loop)."""

    def __init__(self, sess: Session) -> None:
        self.sess = sess
        self.opts = sess.opts

    def _links_up(self) -> None:
        if self.opts.out is None:
            raise ValueError("a run over SocketCAN needs opts.out for candump's log")
        self.sess.prepare_links()

    def candump(self, bus: str) -> FrameSource:
        from bench.run.record.sources import CandumpSource

        self._links_up()
        assert self.opts.out is not None
        return CandumpSource(bus, self.opts.out / "candump.log")

    def box_candump(self, bus: str) -> FrameSource:
        from bench.run.record.sources import BoxCandumpSource

        self._links_up()
        return BoxCandumpSource(self.sess.box, bus)

    def in_process(self) -> FrameSource:
        """A chunk's worth of frames decoded at once (a real-time run's every 0.2 s: its live view)."""
        from bench.run.record.sources import DirectSource

        sess = self.sess
        assert sess.hil is not None and sess.direct is not None
        min_frames = 0 if sess.sc.timing == "realtime" else self.opts.chunk_periods
        source = DirectSource(sess.hil, self.opts.chunk_periods, min_frames=min_frames, fd=sess.sc.frames.fd)
        sess.direct.on_chunk = source.collect
        sess.direct.on_stop = source.release
        return source

    def listener(self) -> FrameSource:
        from bench.run.record.sources import ListenerSource

        source = ListenerSource()
        self.sess.net.notifier.add_listener(source)
        return source
