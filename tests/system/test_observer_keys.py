"""What the observer login hears of a real run through its router: every
message on ``**`` but the world's wake-ups to itself, and the run's tokens
on ``alive/**`` as on ``alive/*/*`` (tests/unit/protocol/test_observer_keys.py
checks the rules without a network)."""

from __future__ import annotations

import threading
from collections import Counter
from pathlib import Path

import pytest
import zenoh

from formation_swarm.launch.launcher import Launch
from formation_swarm.protocol import trust
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.session import make_config

WATCHED = ("alive/**", "alive/*/*", "**")


class Tap:
    """Keys heard on ``**`` (counted by their last part; the wake-up key by name) and the
    tokens each liveliness expression saw appear, each from a session of its own: a
    session's router hands it the tokens of every liveliness subscriber it declared."""

    def __init__(self, keys: Keys) -> None:
        self.keys = keys
        self.lock = threading.Lock()
        self.kinds: Counter[str] = Counter()
        self.tokens: dict[str, set[str]] = {w: set() for w in WATCHED}

    def data(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        with self.lock:
            self.kinds["wake" if key == self.keys.world_wake else key.rsplit("/", 1)[-1]] += 1

    def token(self, watched: str) -> zenoh.handlers.Callback:
        def seen(sample: zenoh.Sample) -> None:
            if sample.kind == zenoh.SampleKind.PUT:
                with self.lock:
                    self.tokens[watched].add(str(sample.key_expr).split("/alive/", 1)[1])

        return seen


@pytest.mark.slow  # a lockstep run of 10 s of sim time as processes, and four observer sessions
def test_the_observer_hears_no_wake_up_and_every_token_on_alive_double_star(tmp_path: Path) -> None:
    login = tmp_path / "observer.json"
    overrides = {"run.duration_s": 10.0}
    launch = Launch("fig11_obstacles", out=tmp_path / "run", logger=False, observer_login=login, overrides=overrides)
    with launch:
        launch.prepare()
        keys = Keys(launch.run_id)
        tap = Tap(keys)
        launch.start()
        conf = make_config("client", [launch.endpoint], connect_timeout_s=30.0, settings=trust.read_settings(login))
        sessions = [zenoh.open(conf) for _ in range(1 + len(WATCHED))]
        try:
            sessions[0].declare_subscriber(keys.everything, tap.data)
            for sess, watched in zip(sessions[1:], WATCHED, strict=True):
                sess.liveliness().declare_subscriber(f"{keys.prefix}/{watched}", tap.token(watched), history=True)
            res = launch.wait(timeout_s=240)
        finally:
            for sess in sessions:
                sess.close()
    assert (res.exit_code, res.summary["ticks"]) == (0, 200)
    with tap.lock:
        kinds, tokens = dict(tap.kinds), {w: sorted(t) for w, t in tap.tokens.items()}
    # The world puts a wake-up about once a deadline or liveliness change (11-12 in 5 s, measured
    # before its key was withheld); none reaches the observer.
    assert "wake" not in kinds, kinds
    assert kinds["obs"] >= 3 * 200, kinds  # measured 600: one per robot and tick
    assert kinds["cmd"] >= 3 * 200, kinds
    every = ["agent/1", "agent/2", "agent/3", "launcher/0", "world/0"]
    assert tokens == {w: every for w in WATCHED}
