"""CPU the world spends per tick on the ROS 2 bridge's sightings (every
robot's observation put once more on ``Keys.sightings``, protocol.sightings),
beside what it spends making and encoding the observations themselves: N
robots in a line on fig11's path (bench/world_tick.py's layout), the puts to
a subscriber in the same Zenoh session.

    python bench/sightings.py [--robots 10 100 200] [--reps 2000]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import zenoh

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))

from world_tick import line_of  # noqa: E402

from formation_swarm.protocol import sightings  # noqa: E402
from formation_swarm.world.tick import WorldTick  # noqa: E402


def per_tick(n: int, reps: int, session: zenoh.Session) -> dict[str, float]:
    """Microseconds of CPU per tick: the observations encoded, the sightings packed, packed and put."""
    world = WorldTick(line_of(n), 0, lockstep=True, wall_s=time.monotonic)
    encoded = world.encoded_observations()
    pub = session.declare_publisher(f"bench/sightings/{n}")
    sub = session.declare_subscriber(f"bench/sightings/{n}", lambda _sample: None)
    out: dict[str, float] = {"bytes": float(sum(len(p) for _, p in encoded)), "puts": len(sightings.pack(encoded))}
    for name, work in (
        ("observe_us", lambda: world.encoded_observations()),
        ("pack_us", lambda: sightings.pack(encoded)),
        ("pack_put_us", lambda: [pub.put(p) for p in sightings.pack(encoded)]),
    ):
        t0 = time.process_time()
        for _ in range(reps):
            work()
        out[name] = (time.process_time() - t0) / reps * 1e6
    sub.undeclare()
    pub.undeclare()
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robots", type=int, nargs="+", default=[10, 100, 200])
    ap.add_argument("--reps", type=int, default=2000)
    args = ap.parse_args()
    print(f"load {os.getloadavg()[0]:.1f}")
    with zenoh.open(zenoh.Config()) as session:
        for n in args.robots:
            r = per_tick(n, args.reps, session)
            print(
                f"{n:5d} robots: {r['bytes'] / 1e3:6.1f} kB of observations in {r['puts']:.0f} puts; "
                f"observations {r['observe_us']:7.0f} us, sightings packed {r['pack_us']:6.1f} us, "
                f"packed and put {r['pack_put_us']:6.1f} us ({r['pack_put_us'] / r['observe_us']:.1%})"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
