"""A follower's role: observations and formation codes in, command and telemetry out.

Each answered tick it finds its reference's marker in the observation's
readings, hands its controller (agents.controller's API, made by
agents.follower.make_controller) what the robot has, and turns the
controller's answer into a command for the world (its wheel speeds),
telemetry for the logger (its target and named values) and its stats (its
stops, its count of filter restarts, its step times: agents.step_times). It
owns the formation codes: checked as they arrive, passed through the
receiving end of the leader -> follower link, kept until their tick.

The leader answers tick k with its code for k; that code can reach the
follower before or after its own observation k (the world publishes them
one by one), so it is flown from tick k + 1 on: never earlier, and in
lockstep never later, since the world publishes k + 1 only after the
leader's answer to k. Codes are taken in the order of their ticks, so one
stamped far ahead cannot hold back the others. A code the link held back
counts from the tick of its release (so it too takes effect on the tick
after).

A controller that raises (in ``step`` or ``prepare``) or returns a wheel
speed that is not a finite number has failed: from that tick on the robot
answers every tick with zero speeds and telemetry without values, the
controller is not called again, the failure is in the stats
(``controller_failure``: tick, error, law) and its traceback in ``notes``
for the process's log. Its ``close()`` (agents.hooks) is called once, by
the process or the engine, when the agent stops.
"""

from __future__ import annotations

import collections
import functools
import math
from collections.abc import Callable, Mapping
from typing import Any

from formation_swarm.agents import hooks
from formation_swarm.agents.controller import (
    HOLDING,
    STATS_VALUES,
    WAITING,
    WIRE_VALUES,
    FollowerController,
    FollowerInput,
    FollowerOutput,
    MarkerReading,
    TargetEstimate,
)
from formation_swarm.agents.formation import Slot
from formation_swarm.agents.geometry import Point
from formation_swarm.agents.role_base import Answer, RoleBase, RoleSetup
from formation_swarm.agents.stops import Stops
from formation_swarm.protocol.links import Link
from formation_swarm.protocol.messages import EXTRA_NAME, MAX_EXTRAS, Command, FormationCode, Observation, Telemetry

PENDING_CODES = 64  # formation codes waiting for their tick
KNOWN_NAMES = frozenset(WIRE_VALUES + STATS_VALUES)  # any other value's name is an extra
MAX_UNSENT_NOTES = 16  # value names that cannot be sent, each said once in the log
STOPPED = FollowerOutput(left_mps=0.0, right_mps=0.0)  # a failed controller's robot, every tick


class FollowerRole(RoleBase):
    NAME = "follower"
    TAKES_CODES = True
    SENDS_TELEMETRY = True

    def __init__(
        self,
        setup: RoleSetup,
        formation_link: Link[FormationCode],
        controller: FollowerController,
        law: str | None = None,
    ) -> None:
        super().__init__(setup)
        self.leader_id = setup.leader_id
        self.dt_s = setup.dt_s
        self.formation_link = formation_link
        self.controller = controller
        self._prepare = getattr(controller, "prepare", None)  # optional (agents.controller)
        self.slot = _slot(self.formations[self.code].slots[self.robot_id])
        self._moved = self._new_reference = False  # since the last step
        # Codes taken, each with the tick it is stamped with or, if the link held it, released at.
        self.pending: collections.deque[tuple[int, FormationCode]] = collections.deque(maxlen=PENDING_CODES)
        self.answered_tick: int | None = None
        self.formation_changes: list[dict[str, Any]] = []
        self.stops = Stops()
        self.ekf_resets = 0
        self._hooked(controller, law)
        self._unsent: set[str] = set()  # telemetry names said not to fit the wire

    @property
    def links(self) -> tuple[Link[Any], ...]:
        return (self.inbox.link, self.formation_link)

    def describe(self) -> str:
        return f"follower of robot {self.slot.reference}"

    # -- what arrives --------------------------------------------------------------

    def take_observation(self, obs: Observation) -> None:
        if self.inbox.take(obs):
            self._take_codes(self.formation_link.due(obs.tick), obs.tick)  # those the link held until now

    def take_code(self, fc: FormationCode) -> None:
        """A formation code that arrived (from the leader only)."""
        if fc.sender != self.leader_id:
            self.rejections.reject("sender mismatch")
        elif (why := self.inbox.checks.code(fc)) is not None:
            self.rejections.reject(why)
        else:
            self._take_codes(self.formation_link.deliver(fc.seq, fc.tick, fc), fc.tick)

    def _take_codes(self, codes: list[FormationCode], release_tick: int) -> None:
        """Codes the formation link handed over at ``release_tick``: one it held
        takes effect as if stamped with the tick of its release."""
        for fc in codes:
            if (why := self.inbox.checks.handed_code(fc)) is not None:
                self.rejections.reject(why)
            elif fc.code >= len(self.formations):
                self.rejections.reject("unknown formation")
            elif self.robot_id not in self.formations[fc.code].slots:
                self.rejections.reject("no slot in formation")
            else:
                self.pending.append((max(fc.tick, release_tick), fc))

    # -- the answer ----------------------------------------------------------------

    def answer(self) -> Answer | None:
        got = self.inbox.pop()
        if got is None:
            return None
        obs, reading = got
        self._fly_due_codes(obs.tick)
        inp = self._input(obs, reading)
        answer = self._controlled(obs, inp) if self.failure is None else None
        if answer is None:  # failed, now or before: stopped
            command = self._command(obs.tick, 0.0, 0.0)
            answer = Answer(command=command, telemetry=self._telemetry(obs, command, STOPPED, {}.get))
        self._answered(obs.tick)
        return answer

    def _controlled(self, obs: Observation, inp: FollowerInput) -> Answer | None:
        """The controller's answer to ``inp``; None when it fails (recorded)."""
        try:
            out = self._step(obs.tick, inp)
            left, right = out.left_mps, out.right_mps
            if not (math.isfinite(left) and math.isfinite(right)):
                raise ValueError(f"wheel speeds must be finite numbers, got left_mps={left!r}, right_mps={right!r}")
            command = self._command(obs.tick, float(left), float(right))
            get = _getter(out.values)
            self._count(obs.tick, out.stop, get)
            telemetry = self._telemetry(obs, command, out, get)
        except Exception as exc:  # noqa: BLE001 - whatever the controller does wrong stops this robot only
            self._fail(obs.tick, exc)
            return None
        return Answer(command=command, telemetry=telemetry)

    def _step(self, tick: int, inp: FollowerInput) -> FollowerOutput:
        """The controller's step, timed (agents.step_times); the first one longer
        than the tick is said in the process's log."""
        self.step_times.start(tick)
        try:
            return self.controller.step(inp)
        finally:
            if (note := self.step_times.first_slow(f"controller {self.law}", tick)) is not None:
                self.notes.append(note)

    def _command(self, tick: int, left_mps: float, right_mps: float) -> Command:
        return Command(
            sender=self.robot_id,
            seq=self._next_seq(),
            tick=tick,
            left_mps=left_mps,
            right_mps=right_mps,
            formation=self.code,
            done=False,
        )

    def prepare(self) -> None:
        if self._prepare is not None and self.failure is None:
            self.step_times.start(self.last_tick or 0, "prepare")  # watched, not counted
            try:
                self._prepare()  # the next tick's EKF prediction, before its observation comes
            except Exception as exc:  # noqa: BLE001 - as in step: this robot stops
                self._fail(self.last_tick or 0, exc)
            finally:
                self.step_times.stop(counted=False)

    def _fail(self, tick: int, exc: Exception) -> None:
        """The controller failed at ``tick``: the robot stops for the rest of the run."""
        self.failure, note = hooks.failure(tick, exc, self.law, self.robot_id)
        self.notes.append(note)

    def _fly_due_codes(self, tick: int) -> None:
        """The codes stamped before ``tick``, in the order of their ticks (then seqs)."""
        if not self.pending or min(t for t, _ in self.pending) >= tick:
            return
        due = sorted((p for p in self.pending if p[0] < tick), key=lambda p: (p[0], p[1].seq))
        self.pending = collections.deque((p for p in self.pending if p[0] >= tick), maxlen=PENDING_CODES)
        for _, fc in due:
            self._fly(fc)

    def _fly(self, fc: FormationCode) -> None:
        if fc.code == self.code:
            return
        new = _slot(self.formations[fc.code].slots[self.robot_id])
        self.code = fc.code
        self._new_reference |= new.reference != self.slot.reference
        self._moved |= new.offset != self.slot.offset
        self.slot = new
        self.formation_changes.append({"tick": fc.tick, "code": fc.code, "name": self.formations[fc.code].name})

    def _input(self, obs: Observation, reading_obs: Observation | None) -> FollowerInput:
        """What the controller gets for ``obs``, read off ``reading_obs``: this
        tick's, or an older one the link held back (stale, as delays are)."""
        reading = None
        if reading_obs is not None:
            ref = self.slot.reference
            for rid, rho, phi, beta in reading_obs.readings:
                if rid == ref:
                    reading = MarkerReading(rho_m=rho, phi_rad=phi, beta_rad=beta)
                    break
        # The ticks since the last one answered: more than one where observations
        # were skipped (real time, a busy machine) or the agent was frozen.
        ticks = 1 if self.answered_tick is None else max(1, obs.tick - self.answered_tick)
        self.answered_tick = obs.tick
        inp = FollowerInput(
            reading=reading,
            slot=self.slot,
            slot_moved=self._moved,
            new_reference=self._new_reference,
            ticks=ticks,
            dt_s=ticks * self.dt_s,
        )
        self._moved = self._new_reference = False
        return inp

    def _count(self, tick: int, stop: str | None, get: Getter) -> None:
        """The stats the controller's answer feeds: its stops (agents.controller.COUNTED_STOPS)
        and the running count of STATS_VALUES."""
        if stop is not None and not isinstance(stop, str):
            raise TypeError(f"stop must be a string or None, got {type(stop).__name__} {stop!r}")
        self.stops.count(tick, holding=stop == HOLDING, waiting=stop == WAITING)
        resets = get("ekf_resets")
        if resets is not None:
            self.ekf_resets = int(resets)

    def _telemetry(self, obs: Observation, command: Command, out: FollowerOutput, get: Getter) -> Telemetry:
        """The tick's telemetry from the controller's answer ``out``, its values read by ``get`` (:func:`_getter`)."""
        steering_to = int(get("steering_to") or 0)
        estimate, cov = _target(out.target)
        return Telemetry(
            sender=self.robot_id,
            seq=self._next_seq(),
            tick=obs.tick,
            time_s=obs.time_s,
            reference=self.slot.reference,
            formation=self.code,
            measured=_values(get, "measured_x_m", "measured_y_m"),
            estimate=estimate,
            target_cov=cov,
            rho_m=get("rho_m"),
            alpha_rad=get("alpha_rad"),
            vn=get("vn_mps"),
            left_mps=command.left_mps,
            right_mps=command.right_mps,
            steering_to=steering_to if 0 <= steering_to <= 3 else 0,
            changing=(get("changing") or 0.0) > 0.0,
            obs_dropped=self.inbox.link.lost,
            formation_dropped=self.formation_link.lost,
            rejected=self.rejections.total,
            extras=() if out.values.keys() <= KNOWN_NAMES else self._extras(out.values),
        )

    def _extras(self, values: Mapping[str, float]) -> tuple[tuple[str, float], ...]:
        """The controller's own named values that fit the wire (MAX_EXTRAS,
        EXTRA_NAME); NaN or infinite ones are left out this tick."""
        out = []
        for name in values:
            if name in KNOWN_NAMES:
                continue
            if len(out) == MAX_EXTRAS or not isinstance(name, str) or EXTRA_NAME.fullmatch(name) is None:
                self._cannot_send(name)
                continue
            if (x := _value(values, name)) is not None:
                out.append((name, x))
        return tuple(out)

    def _cannot_send(self, name: object) -> None:
        if name in self._unsent or len(self._unsent) >= MAX_UNSENT_NOTES:
            return
        self._unsent.add(str(name))
        self.notes.append(
            f"telemetry value {str(name)[:40]!r} is not sent: at most {MAX_EXTRAS} values of its own per tick, each"
            f" named by {EXTRA_NAME.pattern}"
        )

    def stats(self) -> dict[str, Any]:
        return {
            **super().stats(),
            "ekf_resets": self.ekf_resets,
            "held_ticks": self.stops.held_ticks,
            "holds": self.stops.holds,
            "waited_ticks": self.stops.waited_ticks,
            "formation_changes": self.formation_changes,
            "controller_failure": self.failure,
        }


def _slot(slot: Slot) -> Slot:
    return Slot(reference=slot.reference, offset=Point(float(slot.offset[0]), float(slot.offset[1])))


Getter = Callable[[str], "float | None"]  # a named value of the controller's (see _getter)
_FLOAT = frozenset((float,))


def _getter(values: Mapping[str, float]) -> Getter:
    """What reads the controller's named values for the role: each as a float,
    None where it is absent, NaN or infinite (the wire carries neither). A
    value that is no number raises when read (the controller's failure). When
    every value is a finite float (the common case, tested in C for all of
    them at once), the mapping's own ``get``."""
    if (
        isinstance(values, dict)
        and _FLOAT.issuperset(map(type, values.values()))
        and math.isfinite(sum(values.values()))
    ):
        return values.get
    return functools.partial(_value, values)


def _value(values: Mapping[str, float], name: str) -> float | None:
    """A named value; None where it is absent, NaN or infinite. A value that is no number raises."""
    v = values.get(name)
    return None if v is None else _finite(v)


def _finite(v: float) -> float | None:
    """``v`` as a float; None where it is NaN or infinite. A value that is no number raises."""
    if not isinstance(v, float):  # a float (numpy's too) as it is: no new object per value and tick
        v = float(v)
    return v if math.isfinite(v) else None


def _target(target: TargetEstimate | None) -> tuple[tuple[float, float] | None, tuple[float, float, float] | None]:
    """The telemetry's estimate and covariance from the controller's ``target``,
    each None unless every number of it is finite."""
    if target is None:
        return None, None
    x, y = _finite(target.x_m), _finite(target.y_m)
    estimate = None if x is None or y is None else (x, y)
    if target.cov_m2 is None:
        return estimate, None
    if len(target.cov_m2) != 3:
        raise ValueError(f"target.cov_m2 must be (xx, xy, yy), got {target.cov_m2!r}")
    cov = tuple(map(_finite, target.cov_m2))
    return estimate, None if None in cov else cov  # type: ignore[return-value]


def _values(get: Getter, *names: str) -> tuple[float, ...] | None:
    """Named values together; None unless every one is there."""
    got = [get(n) for n in names]
    return None if None in got else tuple(got)  # type: ignore[arg-type]
