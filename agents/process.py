"""One robot's agent process: its brain on the run's Zenoh key space.

    swarm agent --id N --scenario S.toml --run RUN [--seed N] [--stats FILE] --connect ENDPOINT

A follower turns each observation into wheel speeds with the paper's
controller (agents.follower) and obeys the formation codes its leader sends.
The leader flies its scripted path, watches for obstacles and repeats the
formation code to every follower over one-way links: every tick for
``leader.code_burst_s`` after a change, then every ``leader.code_period_s``
(agents.leader.CodeRepeats).

The agent answers every observation it receives, even one its link layer
drops (then without the reading), so that lockstep never waits on a drop.
It holds a liveliness token while it runs and exits when the world says the
run is done, when the world's token disappears, or on SIGINT/SIGTERM.

Observations and formation codes reach the loop through a Zenoh FIFO
channel, received on the loop's own thread: no Python callback thread and no
second queue between the network and the controller (measured on the bare
exchange: ~25% more ticks/s than callback + queue). What would end the loop
(the run's end, the world's departure, a stop signal) closes that channel.
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import gc
import sys
import threading
import time
from typing import Any

import zenoh

from formation_swarm import scenario as scenario_mod
from formation_swarm.agents.follower import Decision, Follower
from formation_swarm.agents.leader import CodeRepeats, FormationSwitch
from formation_swarm.agents.pilot import PathPilot
from formation_swarm.proc import StopEvent, install_stop_handlers, role_inputs, write_json
from formation_swarm.protocol import session
from formation_swarm.protocol.batch import BatchPublisher
from formation_swarm.protocol.codec import Rejections
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.links import Link, link_name
from formation_swarm.protocol.messages import Command, FormationCode, Observation, Status, Telemetry
from formation_swarm.world.kinematics import Pose

STARTUP_TIMEOUT_S = 60.0
WORLD_ID = 0
# Lockstep holds at most a tick's observation and a few codes here; when full,
# Zenoh waits for the loop (back-pressure) rather than dropping.
INBOX_CAPACITY = 1024


class Agent:
    def __init__(self, sess: zenoh.Session, sc: scenario_mod.Scenario, rid: int, run_id: str, seed: int,
                 stop: StopEvent) -> None:  # fmt: skip
        if rid not in sc.robots:
            raise ValueError(f"--id {rid} is not a robot of this scenario; robots are {list(sc.robots)}")
        self.session = sess
        self.sc = sc
        self.rid = rid
        self.keys = Keys(run_id)
        self.stop = stop
        self.is_leader = rid == sc.leader.robot_id
        self.rejections = Rejections()
        self.status_rejections = Rejections()  # counted on the status callback's thread
        self.inbox: zenoh.Subscriber | None = None
        self._inbox_lock = threading.RLock()  # a stop signal may arrive while a callback closes it
        self.seq = 0
        self.code = sc.code_of(sc.leader.formation)
        self.obs_link = Link(link_name("obs", WORLD_ID, rid), sc.links.obs_drop, seed)
        self.formation_link = Link(link_name("formation", sc.leader.robot_id, rid), sc.links.formation_drop, seed)
        self.world_seen = False
        self.world_gone = False
        self.done = False
        self.answered = 0
        self.busy_s = 0.0  # time handling messages in the loop, summed
        self.formation_changes: list[dict[str, Any]] = []
        self.pending_codes: collections.deque[FormationCode] = collections.deque(maxlen=64)
        if self.is_leader:
            ld = sc.leader
            self.pilot = PathPilot(ld.waypoints, ld.speed_mps, sc.width_m, ld.lookahead_m, ld.turn_rate_rps)
            avoid = None if ld.avoid_formation is None else sc.code_of(ld.avoid_formation)
            self.switch = FormationSwitch(self.code, avoid, ld.clear_after_s, sc.dt_s)
            self.repeats = CodeRepeats(ld.code_burst_s, ld.code_period_s, sc.dt_s)
            self.last_cmd = (0.0, 0.0)
        else:
            slot = sc.formation_by_code(self.code).slots[rid]
            self.reference = slot.reference
            self.follower = Follower(sc.followers[rid], slot.offset)

    # -- callbacks: short; they only set a flag and end the loop's wait ----------
    def _on_status(self, sample: zenoh.Sample) -> None:
        st = self.status_rejections.decode(Status, sample.payload.to_bytes())
        if st is not None and st.state == "done":
            self.done = True
            self._close_inbox()

    def _on_world_alive(self, sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.PUT:
            self.world_seen = True
        elif self.world_seen:
            self.world_gone = True
            self._close_inbox()

    def _close_inbox(self) -> None:
        """End the loop: its ``recv`` raises once the messages already queued are read."""
        with self._inbox_lock, contextlib.suppress(zenoh.ZError):  # a stop may come after the session closed
            if self.inbox is not None:
                inbox, self.inbox = self.inbox, None
                inbox.undeclare()

    def run(self) -> int:
        s, k = self.session, self.keys
        self.inbox = s.declare_subscriber(
            k.inbox(self.rid), zenoh.handlers.FifoChannel(INBOX_CAPACITY), allowed_origin=zenoh.Locality.REMOTE
        )
        self.stop.add_waker(self._close_inbox)
        s.declare_subscriber(k.status, self._on_status)
        s.liveliness().declare_subscriber(k.alive("world", 0), self._on_world_alive, history=True)
        # Control messages are never dropped by Zenoh itself (only by our link
        # layer); telemetry, for the logger only, travels in batches.
        block = zenoh.CongestionControl.BLOCK
        self.cmd_pub = s.declare_publisher(k.cmd(self.rid), congestion_control=block)
        self.tel_pub = BatchPublisher(s.declare_publisher(k.telemetry(self.rid)))
        self.form_pubs = (
            {f: s.declare_publisher(k.formation(f), congestion_control=block) for f in self.sc.follower_ids}
            if self.is_leader else {}
        )  # fmt: skip
        # Announce ourselves only once the world can hear our commands.
        deadline = time.monotonic() + STARTUP_TIMEOUT_S
        while not self.cmd_pub.matching_status.matching or (self.is_leader and not all(
                p.matching_status.matching for p in self.form_pubs.values())):  # fmt: skip
            if self.stop.wait(0.01):
                return 130
            if time.monotonic() > deadline:
                print(f"agent {self.rid}: no world (or follower) matched within {STARTUP_TIMEOUT_S:.0f} s",
                      file=sys.stderr)  # fmt: skip
                return 2
        gc.freeze()  # start-up objects (numpy, scipy, zenoh) leave the collector's scans
        token = s.liveliness().declare_token(k.alive("agent", self.rid))
        try:
            return self._loop()
        finally:
            self.tel_pub.close()  # the logger waits for this end-of-stream mark
            token.undeclare()

    def _loop(self) -> int:
        inbox = self.inbox
        if inbox is None:  # closed before we got here
            return self._exit_code()
        # The handler, not the subscriber: closing the subscriber from another
        # thread must not wait for this recv.
        channel = inbox.handler
        while not self.stop.is_set() and not self.done:
            try:
                sample = channel.recv()
            except zenoh.ZError:
                break  # closed by _close_inbox
            t0 = time.perf_counter()
            self._on_message(str(sample.key_expr), sample.payload.to_bytes())
            self.busy_s += time.perf_counter() - t0
        return self._exit_code()

    def _exit_code(self) -> int:
        if self.world_gone and not self.done and not self.stop.is_set():
            print(f"agent {self.rid}: the world is gone; exiting", flush=True)
            return 0
        return 130 if self.stop.is_set() and not self.done else 0

    def _on_message(self, key: str, payload: bytes) -> None:
        rk = self.keys.parse_robot(key)
        if rk is None or rk.robot_id != self.rid:
            self.rejections.reject("unknown key")
            return
        if rk.kind == "obs":
            msg = self.rejections.decode(Observation, payload, sender=WORLD_ID)
            if msg is not None:
                self._on_observation(msg, self.obs_link.accept(msg.seq))
        elif rk.kind == "formation" and not self.is_leader:
            fc = self.rejections.decode(FormationCode, payload, sender=self.sc.leader.robot_id)
            if fc is not None and self.formation_link.accept(fc.seq):
                self._accept_formation(fc)
        else:
            self.rejections.reject("unexpected key")

    def _accept_formation(self, fc: FormationCode) -> None:
        if fc.code >= len(self.sc.formation_names):
            self.rejections.reject("unknown formation")
        elif self.rid not in self.sc.formation_by_code(fc.code).slots:
            self.rejections.reject("no slot in formation")
        else:
            self.pending_codes.append(fc)

    def _apply_formation(self, fc: FormationCode) -> None:
        if fc.code == self.code:
            return
        slot = self.sc.formation_by_code(fc.code).slots[self.rid]
        self.code = fc.code
        self.reference = slot.reference
        self.follower.set_offset(slot.offset)
        self.formation_changes.append({"tick": fc.tick, "code": fc.code, "name": self.sc.formation_names[fc.code]})

    def _on_observation(self, obs: Observation, delivered: bool) -> None:
        if self.is_leader:
            self._lead(obs, delivered)
        else:
            self._follow(obs, delivered)
        self.answered += 1

    def _send_cmd(self, tick: int, left: float, right: float, done: bool = False) -> None:
        self.seq += 1
        self.cmd_pub.put(Command(self.rid, self.seq, tick, left, right, self.code, done).to_bytes())

    def _lead(self, obs: Observation, delivered: bool) -> None:
        if delivered:
            self.code = self.switch.step(obs.obstacles)
            self.last_cmd = self.pilot.step(Pose(*obs.pose))
        if self.repeats.due(self.code):
            for pub in self.form_pubs.values():
                self.seq += 1
                pub.put(FormationCode(self.rid, self.seq, obs.tick, self.code).to_bytes())
        self._send_cmd(obs.tick, *self.last_cmd, done=self.pilot.finished)

    def _follow(self, obs: Observation, delivered: bool) -> None:
        # The leader answers tick k with its code for k; that code can reach us before
        # or after our own observation k (the world publishes them one by one), so it
        # is applied from tick k + 1 on: never earlier, and in lockstep never later,
        # since the world publishes k + 1 only after the leader's answer to k.
        while self.pending_codes and self.pending_codes[0].tick < obs.tick:
            self._apply_formation(self.pending_codes.popleft())
        reading = None
        if delivered:
            for rid, rho, phi, beta in obs.readings:
                if rid == self.reference:
                    reading = (rho, phi, beta)
                    break
        d: Decision = self.follower.step(reading)
        self._send_cmd(obs.tick, d.left_mps, d.right_mps)
        cov = None if d.estimate_cov is None else (
            float(d.estimate_cov[0, 0]), float(d.estimate_cov[0, 1]), float(d.estimate_cov[1, 1]))  # fmt: skip
        self.seq += 1
        self.tel_pub.put(
            Telemetry(
                self.rid,
                self.seq,
                obs.tick,
                obs.time_s,
                self.reference,
                self.code,
                None if d.measured is None else tuple(d.measured),
                None if d.estimate is None else tuple(d.estimate),
                cov,
                _opt(d.rho_m),
                _opt(d.alpha_rad),
                _opt(d.vn),
                d.left_mps,
                d.right_mps,
                int(d.steering_to),
                d.changing,
                self.obs_link.dropped,
                self.formation_link.dropped,
                self.rejections.total,
            ).to_bytes()  # fmt: skip
        )
        self.follower.prepare()  # the next tick's EKF prediction, before its observation comes

    def stats(self) -> dict[str, Any]:
        return {
            "robot": self.rid,
            "role": "leader" if self.is_leader else "follower",
            "answered": self.answered,
            "busy_s": self.busy_s,
            "formation": self.sc.formation_names[self.code],
            "formation_changes": self.formation_changes,
            "links": {
                lk.name: {"received": lk.received, "dropped": lk.dropped}
                for lk in ((self.obs_link,) if self.is_leader else (self.obs_link, self.formation_link))
            },
            "rejected": dict(self.rejections.by_reason + self.status_rejections.by_reason),
        }


def _opt(x: float) -> float | None:
    return None if x != x else x  # NaN -> None (the wire carries no NaN)


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="swarm agent", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--id", type=int, required=True, help="robot id")
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--run", required=True)
    ap.add_argument("--seed", type=int, default=None, help="overrides the scenario's seed (link drops)")
    ap.add_argument("--stats", help="write this agent's counters (JSON) here at exit")
    session.add_arguments(ap, default_mode="client")
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    stop = install_stop_handlers()
    inputs = role_inputs(args, "agent")
    if inputs is None:
        return 2
    sc, sess_cm = inputs
    seed = sc.seed if args.seed is None else args.seed
    with sess_cm as sess:
        try:
            agent = Agent(sess, sc, args.id, args.run, seed, stop)
        except ValueError as exc:
            print(f"agent: {exc}", file=sys.stderr)
            return 2
        code = agent.run()
        write_json(args.stats, agent.stats())
    return code


if __name__ == "__main__":
    sys.exit(main())
