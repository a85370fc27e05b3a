"""Where the logger's recording goes: a stream writing the recording file
and, with a live viewer or the served web viewer, a second stream fed the
same data; the viewer's layout (formation_swarm.nodes.logger.blueprint) is sent to
each. What the messages become: formation_swarm.nodes.logger.recorder.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import rerun as rr

from formation_swarm.nodes.logger import viewer
from formation_swarm.nodes.logger.blueprint import blueprint
from formation_swarm.nodes.logger.columns import batch_s
from formation_swarm.nodes.logger.crowd import CROWD_ROBOTS

if TYPE_CHECKING:
    from formation_swarm.spec.scenario import Scenario

FOOTER_MAX_CHUNKS = 20_000  # about 20 MB of the logger's memory
ENTITIES_PER_ROBOT = 20  # about: a chunk each per batch of the file


def open_recording(
    run_id: str,
    out: Path,
    sc: Scenario,
    live: str | None = None,
    web_ports: tuple[int, int] | None = None,
) -> Recording:
    """The run's recording: a stream writing ``out`` (its folder created) and,
    with ``live`` (a viewer's gRPC address) or ``web_ports`` (gRPC, web: serve
    the web viewer), a second stream fed the same data. A ``live`` address
    where nothing answers is left out (``Recording.dropped`` says why): Rerun
    would hold the logger for seconds at its start and at its end. Rerun
    raises RuntimeError for a sink it cannot open."""
    out.parent.mkdir(parents=True, exist_ok=True)
    bp = blueprint(sc)
    rec = Recording(file=_stream(run_id))
    rec.file.set_sinks(rr.FileSink(str(out), write_footer=footer_fits(sc)))
    sinks: list[Any] = []
    if live and (why := viewer.unreachable(live)) is not None:
        rec.dropped = f"no Rerun viewer answers at {live} ({why})"
    elif live:
        sinks.append(rr.GrpcSink(live))
    if web_ports is not None:
        grpc_port, web_port = web_ports
        server = rr.GrpcServerSink(bind_ip="127.0.0.1", port=grpc_port)
        sinks.append(server)
        rec.web = viewer.web_address(grpc_port, web_port)
    if sinks:
        rec.live = _stream(run_id)
        rec.live.set_sinks(*sinks)
    if web_ports is not None:
        rr.serve_web_viewer(web_port=web_ports[1], connect_to=viewer.grpc_address(web_ports[0]), open_browser=False)
    for stream in rec.streams():
        stream.send_blueprint(bp, make_active=True, make_default=True)
    return rec


def footer_fits(sc: Scenario) -> bool:
    """Whether the file gets Rerun's footer, a manifest of its chunks that the
    stream keeps in memory (about 1 kB per chunk) until the file closes: for
    a run of at most FOOTER_MAX_CHUNKS chunks, estimated from its robots and
    length. A longer run's file has none, and the logger's memory stays
    bounded; the viewer and the report read it the same (as a file cut by a
    kill), only Rerun's random access to it is slower."""
    batches = sc.duration_s / batch_s(len(sc.robots), CROWD_ROBOTS)
    return batches * ENTITIES_PER_ROBOT * len(sc.robots) <= FOOTER_MAX_CHUNKS


def _stream(run_id: str) -> rr.RecordingStream:
    return rr.RecordingStream(
        "formation-swarm", recording_id=run_id, batcher_config=rr.ChunkBatcherConfig(flush_tick=0.1)
    )


@dataclass
class Recording:
    """The recording file's stream and the live one (a viewer, the served web
    viewer), fed the same data. Only the file is flushed while the run lasts:
    a slow or absent viewer never holds the file back."""

    file: rr.RecordingStream
    live: rr.RecordingStream | None = None
    web: str | None = None  # the served web viewer's address
    dropped: str | None = None  # why the --live viewer was left out

    def streams(self) -> list[rr.RecordingStream]:
        return [self.file] if self.live is None else [self.file, self.live]

    def log(self, entity: str, data: Any, static: bool = False) -> None:
        for stream in self.streams():
            stream.log(entity, data, static=static)

    def set_time(self, timeline: str, duration: float) -> None:
        for stream in self.streams():
            stream.set_time(timeline, duration=duration)

    def flush(self, timeout_sec: float) -> None:
        self.file.flush(timeout_sec=timeout_sec)

    def close(self, timeout_s: float = 2.0) -> bool:
        """The file flushed and closed (its footer written), then the live
        stream given ``timeout_s`` to deliver the rest; False when it could
        not: the caller should then leave without waiting on it."""
        with contextlib.suppress(RuntimeError):  # "Flush timed out": closing writes what is left
            self.file.flush(timeout_sec=timeout_s)
        self.file.disconnect()
        if self.live is None:
            return True
        try:
            self.live.flush(timeout_sec=timeout_s)
        except RuntimeError:  # "Flush timed out": the viewer went away or never took it all
            return False
        return True
