"""Lockstep tick rate of the three-robot scenario beside a bare Zenoh exchange.

Both are measured in the same invocation, alternating, so their ratio holds
on a loaded machine:

- bare: a world process (the router) publishes one observation per robot and
  the truth each tick and waits for the three answers; the leader answers
  with a formation code (one put, which the router hands to both followers)
  and a command, each follower with a command and a telemetry message; a
  logger-like process subscribes to the whole key space and only counts.
  Same processes, keys and payload sizes as a run, with no physics,
  camera, controller, EKF or Rerun; every message is sent every tick, one
  put each (a run batches telemetry and truth and repeats the formation code
  less often: the bare figure is the plain exchange). Each role receives
  as ours does: the world and the agents on their loop's thread through a
  Zenoh FIFO channel, the logger through a callback and a queue. It uses
  Zenoh's default configuration, transport included.
- bare, low-latency: the same exchange over the transport every ``swarm``
  process uses (protocol.session: Zenoh's low-latency unicast transport).
- bare + controller: the bare exchange in which each follower, before it
  answers, runs the paper's controller on a camera reading (agents.fuzzy_controller:
  the EKF on filterpy and the two-stage fuzzy controller, as a run's
  follower steps) and, after it, the EKF's next prediction, as a run's
  follower does while it waits. No decoding, checking, physics, camera,
  telemetry content or recording: the rate no design of this shape (one
  process per robot, the paper's controller on filterpy, these messages)
  can pass on this machine, however lean the rest.
- full: ``swarm run scenarios/fig11_obstacles.toml`` in lockstep with the
  logger writing its recording; the rate is the world's loop (ticks / wall s).
- full with the wire recording (on unless ``swarm run --no-record-wire``): what
  recording every message to ``wire.mcap`` costs (each process appends what
  it receives to its spool; the launcher merges them after the run, outside
  the measured loop).
- full without the logger (``--no-logger``): what the recording costs.
- full without authentication (every process a stranger, the router without
  access rules): what the logins and the router's rules cost.

Beside the rates, the CPU every process spends over the exchange, per tick
(the bare roles measure it from their first message; a run's roles report
their loop's): on two cores a run that needs C seconds of CPU per tick cannot
pass 2 / C ticks/s however well its processes overlap, which bounds the
ratio a run can reach before its latency counts.

With ``--robots N`` every variant has N robots (the full runs in a line,
each robot following the one ahead, as bench/scale.py): the bare exchange at
N robots is what one process per robot costs before any of the paper's maths.

    python bench/lockstep.py [--repeat 3] [--ticks 3000] [--robots 3] [--ros2]

``--ros2``: only the full run, without and with its ROS 2 bridge (bench/lockstep_ros2.py).

bench/wire_cost.py measures the wire recording's cost alone (the full run
without and with it, alternating), with more rounds in the same time.
"""

from __future__ import annotations

import argparse
import math
import os
import queue
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))  # lockstep_ros2, also when loaded as a module

import zenoh  # noqa: E402
from lockstep_ros2 import ros2_rounds  # noqa: E402

from formation_swarm.launch.launcher import Launch, free_port  # noqa: E402
from formation_swarm.protocol.keys import Keys  # noqa: E402
from formation_swarm.protocol.session import make_config  # noqa: E402
from formation_swarm.runtime.cliargs import integer  # noqa: E402

OBS = b"o" * 110
CMD = b"c" * 40
FORM = b"f" * 20
TEL = b"t" * 150
TRUTH = b"r" * 160
MIN_TICKS = 100  # fewer would measure mostly the start
ANSWER_TIMEOUT_S = 5.0  # the bare world's longest wait for an answer


def bare_world(endpoint: str, run: str, ticks: int, lowlatency: bool, robots: int) -> None:
    k = Keys(run)
    with zenoh.open(make_config("router", listen=[endpoint], lowlatency=lowlatency)) as s:
        # Received on this thread through a Zenoh FIFO channel, as the world does.
        cmds = s.declare_subscriber(k.all_cmd, zenoh.handlers.FifoChannel(1024))
        answers = cmds.handler
        pubs = [s.declare_publisher(k.obs(r)) for r in range(1, robots + 1)]
        truth = s.declare_publisher(k.truth)
        done = s.declare_publisher(k.status)
        # Each agent's token comes once its subscribers are declared and its command
        # publisher matched us; the logger's once it subscribed (a loaded machine
        # can take seconds for that).
        tokens: set[str] = set()
        s.liveliness().declare_subscriber(k.alive_any, lambda smp: tokens.add(str(smp.key_expr)), history=True)
        deadline = time.monotonic() + start_s(robots)
        while not (
            all(p.matching_status.matching for p in pubs)
            and truth.matching_status.matching
            and len(tokens) >= robots + 1
        ):
            if time.monotonic() > deadline:
                raise SystemExit("bare world: peers never matched")
            time.sleep(0.01)
        # recv has no timeout: a watchdog closes the channel when no answer came
        # for ANSWER_TIMEOUT_S, which ends the wait with an error.
        answered = [0]
        stalled = threading.Event()
        threading.Thread(target=_watchdog, args=(answered, cmds, stalled), daemon=True).start()
        t0, cpu0 = time.perf_counter(), time.process_time()
        try:
            for _ in range(ticks):
                for p in pubs:
                    p.put(OBS)
                truth.put(TRUTH)
                for _ in range(robots):
                    answers.recv()
                answered[0] += 1
        except zenoh.ZError:
            raise SystemExit(f"bare world: no answer within {ANSWER_TIMEOUT_S:g} s") from None
        finally:
            stalled.set()  # ends the watchdog
        rate = ticks / (time.perf_counter() - t0)
        cpu = time.process_time() - cpu0
        done.put(b"done")
        print(f"{rate:.1f} {cpu:.6f}", flush=True)


def start_s(robots: int) -> float:
    """The longest wait for every process to be up: each one's imports take about
    a second of CPU, and N of them share the cores."""
    return 60.0 + 1.0 * robots


def _watchdog(answered: list[int], sub: zenoh.Subscriber, stop: threading.Event) -> None:
    """Close ``sub`` when ``answered[0]`` has not moved for ANSWER_TIMEOUT_S."""
    last, since = answered[0], time.monotonic()
    while not stop.wait(0.5):
        if answered[0] != last:
            last, since = answered[0], time.monotonic()
        elif time.monotonic() - since > ANSWER_TIMEOUT_S:
            sub.undeclare()
            return


def bare_agent(endpoint: str, run: str, rid: int, lowlatency: bool, control: bool = False) -> None:
    k = Keys(run)
    brain = _Brain() if control and rid != 1 else None
    with zenoh.open(make_config("client", [endpoint], lowlatency=lowlatency)) as s:
        # Received on this thread through a Zenoh FIFO channel, as an agent does;
        # "done" closes it, which ends the loop's recv.
        inbox = s.declare_subscriber(
            k.inbox(rid), zenoh.handlers.FifoChannel(1024), allowed_origin=zenoh.Locality.REMOTE
        )
        channel = inbox.handler
        s.declare_subscriber(k.status, lambda _smp: inbox.undeclare())
        cmd = s.declare_publisher(k.cmd(rid))
        tel = s.declare_publisher(k.telemetry(rid))
        form = s.declare_publisher(k.codes) if rid == 1 else None
        deadline = time.monotonic() + start_s(rid)
        while not cmd.matching_status.matching and time.monotonic() < deadline:
            time.sleep(0.01)
        token = s.liveliness().declare_token(k.alive("agent", rid))  # held: dropped, it is undeclared
        cpu0 = None
        while True:
            try:
                m = channel.recv().payload.to_bytes()
            except zenoh.ZError:  # closed by "done"
                token.undeclare()
                print(f"{time.process_time() - (cpu0 or 0.0):.6f}", flush=True)
                return
            cpu0 = time.process_time() if cpu0 is None else cpu0  # from the first observation
            if m == FORM:
                continue
            if form is not None:
                form.put(FORM)
            if brain is not None:
                brain.step(READINGS[brain.ticks % len(READINGS)])
            cmd.put(CMD)
            if rid != 1:
                tel.put(TEL)
            if brain is not None:
                brain.prepare()


# Readings of a reference 1.8-2.2 m ahead, as a follower's camera gives them in a
# formation (rho_r m, phi rad, beta rad); the controller steps through them.
READINGS = [(2.0 + 0.2 * math.sin(i / 7), 0.05 * math.cos(i / 11), 0.1 * math.sin(i / 5)) for i in range(200)]


class _Brain:
    """A run's follower controller (agents.fuzzy_controller.FuzzyController), counting its steps."""

    def __init__(self) -> None:
        from formation_swarm import ControllerSetup, FollowerParams, Point, Slot
        from formation_swarm.agents.follower import FuzzyController

        self.slot = Slot(1, Point(-1.5, -1.5))
        self.params = FollowerParams()
        setup = ControllerSetup(robot_id=2, params=self.params, slot=self.slot, max_wheel_mps=3.0)
        self.follower = FuzzyController(setup)
        self.ticks = 0

    def step(self, reading: tuple[float, float, float]) -> Any:
        """The controller's answer (a FollowerOutput) to ``reading`` (rho_m, phi_rad, beta_rad)."""
        from formation_swarm import FollowerInput, MarkerReading

        rho_m, phi_rad, beta_rad = reading
        marker = MarkerReading(rho_m=rho_m, phi_rad=phi_rad, beta_rad=beta_rad)
        out = self.follower.step(FollowerInput(reading=marker, slot=self.slot, dt_s=self.params.dt_s))
        self.ticks += 1
        return out

    def prepare(self) -> None:
        self.follower.prepare()


def bare_logger(endpoint: str, run: str, lowlatency: bool) -> None:
    k = Keys(run)
    with zenoh.open(make_config("client", [endpoint], lowlatency=lowlatency)) as s:
        q: queue.SimpleQueue[str] = queue.SimpleQueue()
        s.declare_subscriber(k.everything, lambda smp: q.put(str(smp.key_expr)))
        token = s.liveliness().declare_token(k.alive("logger", 0))  # held: dropped, it is undeclared
        q.get()
        cpu0 = time.process_time()  # from the first message
        while not q.get().endswith("/world/status"):
            pass
        token.undeclare()
        print(f"{time.process_time() - cpu0:.6f}", flush=True)


def measure_bare(ticks: int, robots: int, lowlatency: bool = False, control: bool = False) -> tuple[float, float]:
    """Ticks per second, and the CPU of every process over the exchange per tick (s);
    ``control``: the followers run the controller (bare + controller)."""
    run = f"bench-{uuid.uuid4().hex[:8]}"
    ep = f"tcp/127.0.0.1:{free_port()}"
    me = [sys.executable, __file__, "--role"]
    ll = "lowlatency" if lowlatency else "default"
    world = subprocess.Popen([*me, "world", ep, run, ll, str(ticks), str(robots)], stdout=subprocess.PIPE, text=True)
    piped = {"stdout": subprocess.PIPE, "text": True}
    others = [subprocess.Popen([*me, "logger", ep, run, ll], **piped)]
    brain = ["control"] if control else []
    others += [subprocess.Popen([*me, "agent", ep, run, ll, str(r), *brain], **piped) for r in range(1, robots + 1)]
    cpu = 0.0
    try:
        out, _ = world.communicate(timeout=600 + start_s(robots))
        rate, world_cpu = map(float, out.strip().splitlines()[-1].split())
        cpu += world_cpu
    finally:
        for p in others:
            try:
                said, _ = p.communicate(timeout=10)
                cpu += float(said.strip().splitlines()[-1]) if said.strip() else math.nan
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
                cpu = math.nan
    return rate, cpu / ticks


def measure_full(
    duration_s: float, robots: int, logger: bool = True, auth: bool = True, wire: bool = False, ros2: bool = False
) -> tuple[float, dict]:
    overrides: dict[str, object] = {"run.duration_s": duration_s, "leader.waypoints": [[0.0, 0.0], [0.0, 400.0]]}
    if robots != 3:
        overrides |= {"run.robots": robots, "leader.formation": "line"}
    with (
        tempfile.TemporaryDirectory() as tmp,
        Launch(
            ROOT / "scenarios" / "fig11_obstacles.toml",
            out=Path(tmp) / "run",
            logger=logger,
            record_wire=wire,
            auth=auth,
            overrides=overrides | {"ros2.bridge": ros2},
            progress=lambda _l: None,
        ) as launch,
    ):
        res = launch.wait(timeout_s=600)
        if res.exit_code != 0:
            raise SystemExit(f"full run failed: exit {res.exit_code}, see {res.run_dir}")
        return float(res.summary["ticks_per_s"]), res.summary


def full_cpu_per_tick(summary: dict) -> float:
    """The CPU of every process over the run's loop, per tick (s): each role's
    stats say its process's CPU over its loop (all its threads)."""
    return sum(p.get("loop_cpu_s") or 0.0 for p in summary["parts"].values()) / summary["ticks"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "--repeat",
        type=integer(1),
        default=3,
        metavar="N",
        help="rounds, each measuring every variant once; the medians are printed (default 3)",
    )
    ap.add_argument(
        "--ticks",
        type=integer(MIN_TICKS),
        default=3000,
        metavar="N",
        help=f"ticks per measurement, at least {MIN_TICKS} (full: as sim time; default 3000)",
    )
    ap.add_argument(
        "--robots",
        type=integer(3, 500),
        default=3,
        metavar="N",
        help="robots in every variant, 3 to 500 (default 3: fig11 as shipped; more: in a line)",
    )
    ap.add_argument("--ros2", action="store_true", help="only the full run, without and with its ROS 2 bridge")
    ap.add_argument("--role", nargs="+", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.role:
        role, ep, run, transport, *rest = args.role
        ll = transport == "lowlatency"
        if role == "world":
            bare_world(ep, run, int(rest[0]), ll, int(rest[1]))
        elif role == "agent":
            bare_agent(ep, run, int(rest[0]), ll, control=rest[1:] == ["control"])
        else:
            bare_logger(ep, run, ll)
        return
    bare, bare_ll, floor, full, quiet, open_, wired = [], [], [], [], [], [], []
    bare_cpu, floor_cpu, full_cpu = [], [], []
    n = args.robots
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}; {n} robots")
    if args.ros2:
        return ros2_rounds(args.repeat, args.ticks * 0.05, n, measure_full)
    for i in range(args.repeat):
        rate, cpu = measure_bare(args.ticks, n)
        bare.append(rate)
        bare_cpu.append(cpu)
        bare_ll.append(measure_bare(args.ticks, n, lowlatency=True)[0])
        rate, cpu = measure_bare(args.ticks, n, control=True)
        floor.append(rate)
        floor_cpu.append(cpu)
        rate, summary = measure_full(args.ticks * 0.05, n)
        full.append(rate)
        full_cpu.append(full_cpu_per_tick(summary))
        wired.append(measure_full(args.ticks * 0.05, n, wire=True)[0])
        quiet.append(measure_full(args.ticks * 0.05, n, logger=False)[0])
        open_.append(measure_full(args.ticks * 0.05, n, auth=False)[0])
        print(
            f"  round {i + 1}: bare {bare[-1]:7.0f} ticks/s   bare low-latency {bare_ll[-1]:7.0f}   "
            f"bare + controller {floor[-1]:7.0f}   "
            f"full (controller + logger) {full[-1]:7.0f} ticks/s ({summary['ticks']} ticks, "
            f"misses {summary['lockstep_misses']})   with the wire recording {wired[-1]:7.0f} ticks/s   "
            f"without the logger {quiet[-1]:7.0f} ticks/s   "
            f"without authentication {open_[-1]:7.0f} ticks/s   "
            f"CPU per tick, all processes: bare {1e6 * bare_cpu[-1]:.0f} us, "
            f"bare + controller {1e6 * floor_cpu[-1]:.0f} us, full {1e6 * full_cpu[-1]:.0f} us",
            flush=True,
        )
    b, bl, fl = statistics.median(bare), statistics.median(bare_ll), statistics.median(floor)
    f, q, o = statistics.median(full), statistics.median(quiet), statistics.median(open_)
    print(
        f"median: bare {b:.0f} ticks/s, bare low-latency {bl:.0f} ticks/s, full {f:.0f} ticks/s "
        f"(full/bare {f / b:.2f}, full/bare low-latency {f / bl:.2f}), "
        f"without the logger {q:.0f} ticks/s ({q / b:.2f} of bare), "
        f"without authentication {o:.0f} ticks/s ({o / b:.2f} of bare)"
    )
    # The cost as the median of each round's ratio: the rounds run under different loads.
    cost = statistics.median(1 - w / fr for w, fr in zip(wired, full, strict=True))
    print(
        f"the wire recording (--record-wire): full {f:.0f} ticks/s without it, {statistics.median(wired):.0f} "
        f"with it: it costs {100 * cost:.0f}% of the lockstep rate (median of the rounds' ratios)"
    )
    print(
        f"bare + controller (no design of this shape passes it here): {fl:.0f} ticks/s, "
        f"{fl / b:.2f} of bare; full/(bare + controller) {f / fl:.2f}"
    )
    bc, flc, fc = statistics.median(bare_cpu), statistics.median(floor_cpu), statistics.median(full_cpu)
    # Two cores give 2 s of CPU per wall second: a run needing fc per tick cannot
    # pass 2 / fc ticks/s, however its work overlaps.
    print(
        f"CPU per tick, all processes: bare {1e6 * bc:.0f} us, bare + controller {1e6 * flc:.0f} us, "
        f"full {1e6 * fc:.0f} us; the full run's ceiling "
        f"on {os.cpu_count()} cores, all busy: {os.cpu_count() / fc:.0f} ticks/s "
        f"({os.cpu_count() / fc / b:.2f} of bare)"
    )
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
