"""The logger process: the run's key space streamed to Rerun (formation_swarm.recording).

    swarm logger --scenario S.toml --run RUN --out recording.rrd [--live URL] [--serve-web]
                 [--stats FILE] --connect ENDPOINT

It subscribes to the world's keys and to every follower's telemetry (not
to observations, commands and formation codes: they would double the
router's work for nothing) and ends when the world says "done".

Data is buffered and sent as columns every 0.25 s of wall time and the file
is flushed every 0.5 s, so a logger killed with SIGKILL loses at most about
the last second.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import math
import os
import queue
import sys
import threading
import time
from typing import Any

import rerun as rr
import zenoh

from formation_swarm import scenario as scenario_mod
from formation_swarm.proc import StopEvent, install_stop_handlers, role_inputs, write_json
from formation_swarm.protocol import session
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.messages import Rejections, Status, Telemetry, Truth, pack_batch
from formation_swarm.recording import Recorder, blueprint

SEND_PERIOD_S = 0.25
FLUSH_PERIOD_S = 0.5
END_WAIT_S = 1.0  # after "done", for the followers' last telemetry
END_OF_STREAM = pack_batch([])  # what protocol.messages.BatchPublisher.close sends


class Logger:
    """The process loop: messages are queued as they arrive and handed to the
    Recorder, which sends them as Rerun columns, every SEND_PERIOD_S."""

    def __init__(self, sess: zenoh.Session, sc: scenario_mod.Scenario, run_id: str, recorder: Recorder,
                 stop: StopEvent) -> None:  # fmt: skip
        self.session = sess
        self.sc = sc
        self.keys = Keys(run_id)
        self.recorder = recorder
        self.stop = stop
        self.wake = threading.Event()  # set by a stop, the run's status or a stream's end
        stop.add_waker(self.wake.set)
        self.inbox: queue.SimpleQueue[tuple[str, bytes]] = queue.SimpleQueue()
        self.rejections = Rejections()
        self.ended: set[int] = set()  # followers whose telemetry stream has ended
        self.counts = {"truth": 0, "telemetry": 0, "other": 0}
        self.done = False

    def _on_sample(self, sample: zenoh.Sample) -> None:
        key, payload = str(sample.key_expr), sample.payload.to_bytes()
        self.inbox.put((key, payload))
        if key == self.keys.status or payload == END_OF_STREAM:
            self.wake.set()  # the end of the run is handled at once, the rest per send

    def run(self) -> int:
        s, k = self.session, self.keys
        self.recorder.log_static()
        s.declare_subscriber(k.world_all, self._on_sample)
        s.declare_subscriber(k.all_telemetry, self._on_sample)
        gc.freeze()  # start-up objects (numpy, scipy, zenoh) leave the collector's scans
        token = s.liveliness().declare_token(k.alive("logger", 0))
        last_send = last_flush = time.monotonic()
        try:
            # Messages are handled in one go per send, not as they come: the
            # logger then wakes 4 times a second instead of at every batch,
            # out of the way of the run's own processes. After "done", each
            # follower flushes its last telemetry and marks the end of its
            # stream: wait for those (bounded: a killed one never will), then
            # close the file.
            followers, end_by = set(self.sc.follower_ids), math.inf
            while not self.stop.is_set() and not (self.done and (self.ended >= followers or time.monotonic() > end_by)):
                self.wake.wait(max(0.0, min(last_send + SEND_PERIOD_S, end_by) - time.monotonic()))
                self.wake.clear()
                self._drain()
                now = time.monotonic()
                if self.done and end_by == math.inf:
                    end_by = now + END_WAIT_S
                if now - last_send >= SEND_PERIOD_S:
                    self.recorder.send()
                    last_send = now
                if now - last_flush >= FLUSH_PERIOD_S:
                    self.recorder.flush(timeout_s=0.2)
                    last_flush = now
            # Handle what already arrived, then close the file properly.
            self._drain()
            self.recorder.send(final=True)
            self.recorder.flush(timeout_s=1.0)
        finally:
            token.undeclare()
        return 0

    def _drain(self) -> None:
        while True:
            try:
                self._handle(*self.inbox.get_nowait())
            except queue.Empty:
                return

    def _handle(self, key: str, payload: bytes) -> None:
        rk = self.keys.parse_robot(key)
        if key == self.keys.truth:
            truths = self.rejections.decode_batch(Truth, payload) or []
            self.counts["truth"] += len(truths)
            self.recorder.add_truths(truths)
        elif rk is not None and rk.kind == "telemetry":
            tels = self.rejections.decode_batch(Telemetry, payload, sender=rk.robot_id)
            if tels == []:
                self.ended.add(rk.robot_id)
            elif tels is not None:
                self.counts["telemetry"] += len(tels)
                self.recorder.add_telemetry(tels)
        elif key == self.keys.status:
            st = self.rejections.decode(Status, payload)
            if st is not None and st.state == "done":
                self.done = True
        else:
            self.counts["other"] += 1

    def stats(self) -> dict[str, Any]:
        recorded = self.recorder.stats()
        return {
            "messages": {**self.counts, **self.recorder.counts},
            "last_sim_time_s": recorded["last_sim_time_s"],
            "target_errors": recorded["target_errors"],
            "rejected": dict(self.rejections.by_reason),
        }


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="swarm logger", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--run", required=True)
    ap.add_argument("--out", required=True, help="the .rrd file to write")
    ap.add_argument("--live", metavar="URL", help="also stream to a viewer, e.g. rerun+http://127.0.0.1:9876/proxy")
    ap.add_argument("--serve-web", action="store_true", help="also serve the web viewer (gRPC + web ports)")
    ap.add_argument("--grpc-port", type=int, default=9876, help="--serve-web: the gRPC port (default 9876)")
    ap.add_argument("--web-port", type=int, default=9090, help="--serve-web: the web viewer's port (default 9090)")
    ap.add_argument("--stats", help="write the logger's counters (JSON) here at exit")
    ap.add_argument("--nice", type=int, default=10, help="scheduling niceness increment (default 10; 0 keeps it)")
    session.add_arguments(ap, default_mode="client")
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    stop = install_stop_handlers()
    if args.nice:
        # Off the lockstep critical path: yield the cores to the world and the
        # agents; the logger buffers and catches up in their slack.
        with contextlib.suppress(OSError):
            os.nice(args.nice)
    inputs = role_inputs(args, "logger")
    if inputs is None:
        return 2
    sc, sess_cm = inputs
    with sess_cm as sess:
        rec = rr.RecordingStream("formation-swarm", recording_id=args.run,
                                 batcher_config=rr.ChunkBatcherConfig(flush_tick=0.1))  # fmt: skip
        sinks: list[Any] = [rr.FileSink(args.out)]
        if args.live:
            sinks.append(rr.GrpcSink(args.live))
        rec.set_sinks(*sinks, default_blueprint=blueprint())
        if args.serve_web:
            url = rr.serve_grpc(grpc_port=args.grpc_port, recording=rec, default_blueprint=blueprint())
            rr.serve_web_viewer(web_port=args.web_port, connect_to=url, open_browser=False)
            print(f"logger: web viewer on http://127.0.0.1:{args.web_port}, data at {url}", flush=True)
        logger = Logger(sess, sc, args.run, Recorder(rec, sc), stop)
        code = logger.run()
        write_json(args.stats, logger.stats())
    rec.flush(timeout_sec=2.0)
    return code


if __name__ == "__main__":
    sys.exit(main())
