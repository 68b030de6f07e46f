"""What the simulated PTU-D46 does with a command: its state, kinematics and answers.

No I/O and no clock: time is passed in (``now``, s, any monotonic clock). The
pseudo-terminal side lives in ``ptu_sim.py``. Numbers are those of a PTU-D46-17
(reference notes, section 4): 185.1428 arcsec/step, pan -3090..3090, tilt -907..604,
speed 31..2902 steps/s, base speed 1000 steps/s, acceleration 2000 steps/s^2.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from drivers.ptu_protocol import Command, Reply, ReplyKind, format_reply, parse_token

RESOLUTION_ARCSEC = 185.1428
PAN_LIMITS = (-3090, 3090)
TILT_LIMITS = (-907, 604)
SPEED_BOUNDS = (31, 2902)
BASE_SPEED = 1000
ACCEL = 2000
AXIS_NAME = {"P": "Pan", "T": "Tilt"}


def advance(pos: float, vel: float, target: float, vmax: float, accel: float,
            dt: float, h: float = 1e-3) -> tuple[float, float]:
    """Move one axis for ``dt`` s towards ``target`` (steps) with |v| <= vmax, |a| <= accel.

    Time-optimal bang-bang profile integrated in sub-steps of at most ``h`` s: the
    desired velocity is the largest one from which the axis can still stop at the
    target, ``sign(d) min(vmax, sqrt(2 accel |d|))``; the velocity approaches it at
    ``accel`` and never carries the axis past the target within one sub-step.
    Returns the new (position, velocity) in steps and steps/s.
    """
    if dt <= 0.0:
        return pos, vel
    n = max(1, math.ceil(dt / h))
    h = dt / n
    dv_max = accel * h
    for _ in range(n):
        d = target - pos
        if abs(d) < 1e-6 and abs(vel) <= dv_max:
            pos, vel = target, 0.0
            break
        # braking speed of the discrete profile: v^2 / (2 a) + v h / 2 = |d|
        v_brake = math.sqrt((0.5 * dv_max) ** 2 + 2.0 * accel * abs(d)) - 0.5 * dv_max
        v_des = math.copysign(min(vmax, v_brake), d)
        new_vel = vel + min(dv_max, max(-dv_max, v_des - vel))
        if new_vel * d > 0.0:
            new_vel = math.copysign(min(abs(new_vel), abs(d) / h), d)   # land on the target
        pos += new_vel * h
        vel = new_vel
    return pos, vel


@dataclass
class Axis:
    """Mutable state of one axis; positions in steps, speeds in steps/s."""

    lo: int
    hi: int
    pos: float = 0.0
    vel: float = 0.0
    target: float = 0.0
    speed: int = BASE_SPEED
    accel: int = ACCEL
    t: float = 0.0

    def at(self, now: float) -> float:
        self.pos, self.vel = advance(self.pos, self.vel, self.target, self.speed, self.accel,
                                     now - self.t)
        self.t = max(self.t, now)
        return self.pos

    def time_to_target(self) -> float:
        """s until the axis rests at its target (simulated on a copy; at most 60 s)."""
        pos, vel, t = self.pos, self.vel, 0.0
        while (pos != self.target or vel != 0.0) and t < 60.0:
            pos, vel = advance(pos, vel, self.target, self.speed, self.accel, 0.01)
            t += 0.01
        return t


@dataclass(frozen=True)
class Answer:
    """Bytes the unit sends for one command and the delay before it sends them, s."""

    data: bytes
    delay_s: float = 0.0


class UnitModel:
    """Command interpreter of the simulated unit."""

    def __init__(self, reset_duration_s: float = 0.2) -> None:
        self.reset_duration_s = reset_duration_s
        self.axes = {"P": Axis(*PAN_LIMITS), "T": Axis(*TILT_LIMITS)}
        self.power_up(0.0)

    def power_up(self, now: float) -> None:
        """Factory state: echo on, verbose feedback, limits on, immediate, position mode."""
        self.echo = True
        self.verbose = True
        self.limits = True
        self.slaved = False
        self.mode = "CI"
        self.pending: dict[str, float] = {}
        for axis in self.axes.values():
            axis.pos = axis.vel = axis.target = 0.0
            axis.speed, axis.accel, axis.t = BASE_SPEED, ACCEL, now

    def position(self, now: float) -> tuple[float, float]:
        return self.axes["P"].at(now), self.axes["T"].at(now)

    def answer_error(self, raw: str, message: str) -> Answer:
        return Answer(self._format(Reply(ReplyKind.ERROR, message), raw))

    def execute(self, raw: str, now: float) -> Answer:
        """Carry out the command token ``raw`` at time ``now``; what to answer and when."""
        for axis in self.axes.values():
            axis.at(now)
        echo = self.echo   # the unit echoes while it receives, before executing (e.g. ED)
        cmd = parse_token(raw.encode("latin-1"))
        reply, delay = self._dispatch(cmd, now)
        return Answer(format_reply(reply, echo=raw if echo else None), delay)

    def _format(self, reply: Reply, raw: str) -> bytes:
        return format_reply(reply, echo=raw if self.echo else None)

    def _value(self, label: str, value: object) -> Reply:
        text = f"{label} is {value}" if self.verbose else str(value)
        return Reply(ReplyKind.OK, text)

    def _dispatch(self, cmd: Command, now: float) -> tuple[Reply, float]:
        ok = Reply(ReplyKind.OK)
        op, arg = cmd.op, cmd.arg
        if not cmd.known:
            return Reply(ReplyKind.ERROR, "Illegal command"), 0.0
        simple = {"ED": ("echo", False), "EE": ("echo", True), "FT": ("verbose", False),
                  "FV": ("verbose", True), "LE": ("limits", True), "LD": ("limits", False),
                  "I": ("slaved", False), "S": ("slaved", True)}
        if op in simple and arg is None:
            attr, value = simple[op]
            setattr(self, attr, value)
            return ok, 0.0
        if op in ("CI", "CV"):
            self.mode = op
            return ok, 0.0
        queries: dict[str, tuple[str, Callable[[], str]]] = {
                   "E": ("Echoing", lambda: "ON" if self.echo else "OFF"),
                   "F": ("Feedback", lambda: "VERBOSE" if self.verbose else "TERSE"),
                   "L": ("Limits", lambda: "ENABLED" if self.limits else "DISABLED"),
                   "C": ("Control mode", lambda: self.mode),
                   "V": ("Version", lambda: "PTU-D46 simulator v1.0"),
                   "O": ("Voltage and temperature", lambda: "12.0V 77F")}
        if op in queries and arg is None:
            label, fn = queries[op]
            return self._value(label, fn()), 0.0
        if op in ("DS", "DR", "DF") and arg is None:
            return ok, 0.0
        if op == "A" and arg is None:
            self._apply_pending()
            return ok, max(a.time_to_target() for a in self.axes.values())
        if op in ("H", "HP", "HT") and arg is None:
            for key in ("P", "T") if op == "H" else (op[1],):
                axis = self.axes[key]
                stop = axis.vel * abs(axis.vel) / (2.0 * axis.accel)
                axis.target = round(axis.pos + stop)
            return ok, 0.0
        if op in ("R", "RP", "RT") and arg is None:
            keys = ("T", "P") if op == "R" else (op[1],)
            for key in keys:
                axis = self.axes[key]
                axis.pos = axis.vel = axis.target = 0.0
            return self._reset_reply(keys), self.reset_duration_s
        if len(op) == 2 and op[0] in "PT":
            return self._axis_command(op[0], op[1], arg), 0.0
        return Reply(ReplyKind.ERROR, "Illegal argument"), 0.0

    def _reset_reply(self, keys: tuple[str, ...]) -> Reply:
        # '!T!T!P!P*': the limit hits of the calibration run, then success. Sent as a
        # raw line (format_reply sends BANNER text unchanged).
        return Reply(ReplyKind.BANNER, "".join(f"!{k}!{k}" for k in keys) + "*")

    def _apply_pending(self) -> None:
        for key, target in self.pending.items():
            self.axes[key].target = target
        self.pending.clear()

    def _axis_command(self, key: str, what: str, arg: int | None) -> Reply:
        axis, name = self.axes[key], AXIS_NAME[key]
        if what in ("P", "O"):
            if arg is None:
                value = round(axis.pos) if what == "P" else round(axis.target)
                label = f"Current {name} position" if what == "P" else f"Target {name} position"
                return self._value(label, value)
            target = arg if what == "P" else round(axis.target) + arg
            if self.limits and target > axis.hi:
                return Reply(ReplyKind.ERROR, f"Maximum allowable {name} position is {axis.hi}")
            if self.limits and target < axis.lo:
                return Reply(ReplyKind.ERROR, f"Minimum allowable {name} position is {axis.lo}")
            if self.slaved:
                self.pending[key] = float(target)
            else:
                axis.target = float(target)
            return Reply(ReplyKind.OK)
        if what == "R" and arg is None:
            return self._value(f"{name} resolution", f"{RESOLUTION_ARCSEC:.4f}")
        limits = {"N": (f"Minimum {name} position", axis.lo),
                  "X": (f"Maximum {name} position", axis.hi),
                  "L": (f"{name} lower speed limit", SPEED_BOUNDS[0]),
                  "U": (f"{name} upper speed limit", SPEED_BOUNDS[1]),
                  "B": (f"{name} base speed", BASE_SPEED)}
        if what in limits and arg is None:
            label, value = limits[what]
            return self._value(label, value)
        if what == "S":
            if arg is None:
                return self._value(f"Target {name} speed", axis.speed)
            if arg > SPEED_BOUNDS[1]:
                return Reply(ReplyKind.ERROR,
                             f"{name} speed cannot exceed {SPEED_BOUNDS[1]} positions/sec")
            if arg < SPEED_BOUNDS[0]:
                return Reply(ReplyKind.ERROR,
                             f"Motor speed cannot be less than {SPEED_BOUNDS[0]} pos/sec")
            axis.speed = arg
            return Reply(ReplyKind.OK)
        if what == "A":
            if arg is None:
                return self._value(f"{name} acceleration", axis.accel)
            if axis.vel != 0.0:
                return Reply(ReplyKind.ERROR, f"{name} acceleration cannot be changed on the fly")
            if arg <= 0:
                return Reply(ReplyKind.ERROR, "Illegal argument")
            axis.accel = arg
            return Reply(ReplyKind.OK)
        return Reply(ReplyKind.ERROR, "Illegal argument")
