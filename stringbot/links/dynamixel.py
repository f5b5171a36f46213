"""The Dynamixel link: hooking moves -> two X-series servos through the official ``dynamixel_sdk``.

The ring servo runs in Extended Position Control Mode (multi-turn), the head
servo in Position Control Mode; both on one Protocol 2.0 bus.  Every move is
written as Goal Position(s) and :meth:`DynamixelLink.run_step` returns only
when the servos report Moving = 0 at their goals (read back by polling the
servos that move: one read, or one sync read when both move), so a step that
returned was executed.

Failures are one clear :class:`~stringbot.errors.MachineFailure` each, naming
the servo (role and id), the step and the pin: a servo that does not answer
(``COMM_RX_TIMEOUT`` after retries), a corrupted answer (``COMM_RX_CORRUPT``,
retried first), a hardware error by name (``Overload Error``), a refused write
by name (``Data Range Error``), a servo that lost torque (power loss or
reboot), a move that does not arrive in time.

Positions: ring ticks = ring_deg / 360 * gear_ratio * ticks_per_turn (Goal
Position, within the extended range -1,048,575..1,048,575); head ticks map
linearly head_in_ticks..head_out_ticks <-> head.in_mm..head.out_mm.

Resume after a power loss or a reboot: the ring servo then reports its
position within one turn (:attr:`DynamixelLink.position_lost`).
``prepare(resume_at=(ring_deg, head_mm))`` or ``set_position(ring_deg,
head_mm)``, given where the ring was last seen with torque on
(:meth:`DynamixelLink.position`, which the journal keeps), adds the whole
turns back through Homing Offset (20), so that Present Position is again the
ring's multi-turn position.  That is exact as long as the ring is within half
a servo turn of the hint.  :meth:`DynamixelLink.stop_point` says which move of
which step to re-issue: each move is an absolute single-axis target, so the
rest of the interrupted step finishes the same path and no pin is hooked twice.

The wind loop's interface (``stringbot.winding``): ``identify``, ``prepare``,
``execute``, ``execute_lines`` (the rest of a step: Moves), ``finish``,
``hold``, ``take_executed``, ``status``, ``position``, ``home``,
``set_position``, ``unlock``, ``flush``, ``close``; ``info``, ``lines_sent``,
``on_move``, ``position_lost``, ``stop_point()``.
"""

import logging
import time
from dataclasses import dataclass

import serial

from firmware_protocol import dynamixel as dx

from ..errors import BadInput, MachineFailure
from .base import FirmwareInfo, LinkState, Status
from .dynamixel_axes import ServoAxes
from .dynamixel_bus import ServoBus, comm_name
from .dynamixel_motion import ServoMoves

__all__ = ["DynamixelLink", "ServoInfo", "open_dynamixel_link", "comm_name"]

log = logging.getLogger(__name__)

CT = dx.CONTROL_TABLE


@dataclass(frozen=True)
class ServoInfo:
    role: str            # "ring" or "head"
    id: int
    model: int
    firmware: int

    @property
    def model_name(self):
        return dx.MODELS.get(self.model, f"model {self.model}")


class DynamixelLink(ServoMoves):
    """Two X-series servos (ring, head) on one bus.

    Parameters
    ----------
    machine : firmware_protocol.machine.Machine
        A machine with ``controller.kind = "dynamixel"``.
    port : str
        A serial device (``/dev/ttyUSB0``, the emulator's pty path) or a pyserial URL.
    retries : int
        Extra attempts after a failed exchange (no answer, corrupted answer).
    arrival_slack_s : float
        Seconds allowed beyond twice the profile's time for a move to arrive.

    Its moves (``run_step``, ``move_to``: goals written, arrival waited for) are
    :class:`~stringbot.links.dynamixel_motion.ServoMoves`'.
    """

    def __init__(self, machine, port, *, retries=3, arrival_slack_s=2.0):
        if machine["controller.kind"] != "dynamixel":
            raise BadInput(f"machine {machine.name!r} has controller.kind = "
                           f"{machine['controller.kind']!r}; the Dynamixel link needs 'dynamixel'")
        self.machine = machine
        self.url = str(port)
        self.retries = retries
        self.arrival_slack_s = arrival_slack_s
        c = lambda key: machine[f"controller.{key}"]
        self.axes = ServoAxes(machine)
        self.tpt = self.axes.tpt
        self.ring_ticks, self.ring_deg = self.axes.ring_ticks, self.axes.ring_deg
        self.head_ticks, self.head_mm = self.axes.head_ticks, self.axes.head_mm
        self.head_in, self.head_out = self.axes.head_in, self.axes.head_out
        self.ids = {"ring": c("ring_id"), "head": c("head_id")}
        self.role = {v: k for k, v in self.ids.items()}
        self.state = LinkState.CLOSED
        self.servos = {}
        self.goal = {}              # id -> last Goal Position written
        self.present = {}           # id -> last Present Position read
        self.where = (None, None)   # (step, pin) running, for messages
        self._move_index = None
        self._step_index = None
        self._velocity_limit = None   # the slowest servo's Velocity Limit (44), read by prepare
        self.on_move = None           # the wind loop's on_move(step, move_index) after each arrival
        self._ref = {}                # id -> (ticks, exact value) last commanded or declared
        self.position_lost = False    # a servo lost torque: positions may be re-based until resumed
        self.info = None
        self._executed = []         # steps executed but not yet handed to the wind loop
        self._arrival_ticks = {self.ids["ring"]: self.axes.ring_arrival, self.ids["head"]: self.axes.head_arrival}
        self.bus = ServoBus(self.url, self.role, self._fail, protocol=c("protocol"), retries=retries)

    # ---- failures ---------------------------------------------------------------------------
    def _fail(self, message):
        self.state = LinkState.FAILED
        step, pin = self.where
        return MachineFailure(message, step=step, pin=pin)

    def _name(self, servo_id):
        return self.bus.name(servo_id)

    def _read(self, servo_id, name):
        return self.bus.read(servo_id, name)

    def _write(self, servo_id, name, value):
        self.bus.write(servo_id, name, value)

    @property
    def polls(self):
        return self.bus.polls

    @property
    def retried(self):
        return self.bus.retried

    # ---- life -------------------------------------------------------------------------------
    def open(self):
        """Open the port at ``controller.baud`` (no bus traffic yet)."""
        if self.state is not LinkState.CLOSED:
            return
        try:
            opened = self.bus.open(self.machine["controller.baud"])
        except (serial.SerialException, OSError, ValueError) as exc:
            first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise BadInput(f"cannot open port {self.url!r}: {first}; give --port the servo adapter's "
                           "device (e.g. /dev/ttyUSB0) or the emulator's pty") from None
        if not opened:
            raise BadInput(f"controller.baud = {self.machine['controller.baud']} is not a baud rate the "
                           "Dynamixel SDK supports; expected e.g. 57600, 115200, 1000000, 2000000, 4000000")
        self.state = LinkState.OPEN

    def connect(self):
        """Open the port, ping both servos, check their models.  Returns [ServoInfo]."""
        self.open()
        expected = self.machine["controller.model_number"]
        for role, servo_id in self.ids.items():
            model = self.bus.ping(servo_id)
            firmware = self.bus.read(servo_id, "Firmware Version", alert_ok=True)   # prepare reboots
            if expected is not None and model != expected:
                raise self._fail(f"{self._name(servo_id)} is a {dx.MODELS.get(model, f'model {model}')} "
                                 f"(model number {model}); the machine file expects controller.model_number = "
                                 f"{expected} ({dx.MODELS.get(expected, 'unknown model')})")
            if expected is None and model not in dx.MODELS:
                log.warning("%s has model number %d, not a known X-series servo: the control table "
                            "this link uses may not match", self._name(servo_id), model)
            self.servos[servo_id] = ServoInfo(role, servo_id, model, firmware)
        self.state = LinkState.IDENTIFIED
        models = sorted({s.model_name for s in self.servos.values()})
        self.info = FirmwareInfo(dialect="dynamixel", name=f"Dynamixel {' + '.join(models)}",
                                 version=f"fw {'/'.join(str(s.firmware) for s in self.servos.values())}",
                                 lines=(self.describe(),))
        log.info("connected: %s", self.describe())
        return list(self.servos.values())

    def describe(self):
        parts = [f"{s.role} id {s.id}: {s.model_name} fw {s.firmware}" for s in self.servos.values()]
        return f"Dynamixel Protocol 2.0 on {self.url} ({'; '.join(parts)})"

    def prepare(self, *, home=False, resume_at=None):
        """Torque off, modes, profile, torque on.  Returns the machine's position (ring_deg, head_mm).

        The ring's turn count is kept as the servo has it.  ``home``: clear it
        (the ring is then within one servo turn of 0; see :meth:`home`).
        ``resume_at=(ring_deg, head_mm)``: a ring servo that lost its turn count
        (power loss, reboot) is re-based by whole turns to the position nearest
        ``resume_at`` (see :meth:`set_position`).  Afterwards :attr:`position_lost`
        is True when the ring came up without torque and neither happened: its
        turn count may be wrong, and a resume must declare the position.
        """
        ring, head = self.ids["ring"], self.ids["head"]
        for servo_id in (ring, head):
            bits = self._read(servo_id, "Hardware Error Status")
            if bits:
                log.warning("%s had a hardware error (%s): rebooting it", self._name(servo_id),
                            ", ".join(dx.hardware_error_names(bits)))
                self.bus.reboot(servo_id)
                time.sleep(0.1)
            limit = self._read(servo_id, "Velocity Limit")
            self._velocity_limit = min(self._velocity_limit or limit, limit) or 1023
            if self.machine["controller.profile_velocity"] > limit:
                raise BadInput(f"{self.machine.path}: controller.profile_velocity = "
                               f"{self.machine['controller.profile_velocity']} exceeds the {self._name(servo_id)}'s "
                               f"Velocity Limit (44) = {limit}; expected <= {limit}")
        torque_was_on = self._read(ring, "Torque Enable") == 1
        for servo_id in (ring, head):
            self._write(servo_id, "Torque Enable", 0)
        for servo_id, mode in ((ring, dx.OperatingMode.EXTENDED_POSITION), (head, dx.OperatingMode.POSITION)):
            if self._read(servo_id, "Operating Mode") != mode:
                self._write(servo_id, "Operating Mode", mode)
        if home:
            self._clear_turns()
        if resume_at is not None:
            self._rebase(resume_at[0], torque_was_on)
            self._remember(*resume_at)
        for servo_id in (ring, head):
            self._write(servo_id, "Profile Acceleration", self.machine["controller.profile_acceleration"])
            self._write(servo_id, "Profile Velocity", self.machine["controller.profile_velocity"])
            self._write(servo_id, "Torque Enable", 1)
            self.present[servo_id] = self.goal[servo_id] = self._read(servo_id, "Present Position")
        self.state = LinkState.READY
        self.position_lost = not (torque_was_on or home or resume_at is not None)
        log.info("ready at ring %.3f deg, head %.3f mm", *self.position())
        return self.position()

    def _clear_turns(self):
        """Homing Offset 0 and the turn count cleared: the ring within one servo turn of 0 (torque off)."""
        ring = self.ids["ring"]
        self._write(ring, "Homing Offset", 0)
        self.bus.clear_multi_turn(ring)

    def _rebase(self, hint_deg, torque_was_on):
        """Add the whole servo turns that bring the ring nearest ``hint_deg`` (torque off)."""
        ring = self.ids["ring"]
        present = self._read(ring, "Present Position")
        want = self.ring_ticks(hint_deg)
        turns = round((want - present) / self.tpt)
        if torque_was_on or turns == 0:
            if turns:
                log.warning("ring servo kept power but is %d turns from where the journal left it; "
                            "trusting the servo", turns)
            return
        offset = self._read(ring, "Homing Offset") + turns * self.tpt
        if abs(offset) > CT["Homing Offset"].hi:
            raise self._fail(f"cannot re-base the ring servo by {turns} turns: Homing Offset {offset} "
                             "is outside +-1,044,479")
        self._write(ring, "Homing Offset", offset)
        now = self._read(ring, "Present Position")
        log.warning("ring servo had lost its turn count (power loss or reboot): re-based by %d turns, "
                    "%d -> %d ticks (expected about %d)", turns, present, now, want)

    @property
    def position_tolerance(self):
        """(ring_deg, head_mm): how far :meth:`position` may be from a planned point the servos
        arrived at (the arrival tolerance plus half a tick of rounding)."""
        return self.axes.tolerance

    def position(self):
        """The last position read back with torque on: (ring_deg, head_mm).

        An axis standing within its arrival tolerance of the point last commanded
        (or declared) reports that point exactly, not its tick-rounded reading, so
        that positions compare equal to the plan's.
        """
        out = []
        for servo_id, to_units, default in ((self.ids["ring"], self.ring_deg, 0),
                                            (self.ids["head"], self.head_mm, self.head_in)):
            ticks = self.present.get(servo_id, default)
            ref = self._ref.get(servo_id)
            near = ref is not None and abs(ticks - ref[0]) <= self._arrival_ticks[servo_id]
            out.append(ref[1] if near else to_units(ticks))
        return tuple(out)

    def _remember(self, ring_deg=None, head_mm=None):
        """The exact point last commanded or declared, per axis."""
        if ring_deg is not None:
            self._ref[self.ids["ring"]] = (self.ring_ticks(ring_deg), float(ring_deg))
        if head_mm is not None:
            self._ref[self.ids["head"]] = (self.head_ticks(head_mm), float(head_mm))

    # ---- the wind loop's interface (stringbot.winding) ---------------------------------------
    def identify(self):
        """Ping both servos and check their models; returns :class:`FirmwareInfo`."""
        self.connect()
        return self.info

    def execute(self, steps, on_executed=None):
        """Run ``steps`` in order; ``on_executed(step)`` after each one has arrived."""
        for step in steps:
            self.run_step(step, on_executed=on_executed)

    def execute_lines(self, step, moves, on_executed=None):
        """Run the rest of ``step`` after a stop: ``moves`` are its Moves from the interrupted one on.

        Each Move is an absolute target, so re-issuing the interrupted move from
        wherever the axes stopped finishes the same straight path (see :meth:`stop_point`).
        """
        self.run_step(step, moves=moves, on_executed=on_executed)

    def finish(self):
        """Nothing to park: the last step ends with the head IN; torque stays on."""
        self.state = LinkState.READY

    def take_executed(self):
        done, self._executed = self._executed, []
        return done

    def status(self):
        """A firmware-neutral :class:`Status`; ``mpos`` = (ring_deg, head_mm) last read back."""
        state = {LinkState.HOLDING: "Hold", LinkState.FAILED: "Alarm"}.get(self.state, "Idle")
        return Status(state=state, sub="0" if state == "Hold" else "", mpos=self.position(),
                      fields={"stop": self.stop_point()})

    def stop_point(self):
        """Where a stop left the job: ``{"step_index", "move", "position"}`` for the journal.

        ``step_index`` is the first step not yet handed to the wind loop as executed
        and ``move`` the first of its moves not known to have arrived (the one
        that was running; ``len(step.moves)`` when all had).  Resume with
        ``prepare(resume_at=position)`` then ``execute_lines(step, step.moves[move:])``:
        each Move is an absolute target, so re-issuing the interrupted one from
        where the axes stopped finishes the same path, and no pin is hooked twice.
        """
        return {"step_index": self._step_index, "move": self._move_index, "position": list(self.position())}

    def home(self):
        """Clear the ring's turn count (Homing Offset 0): it is then within one servo turn of 0.

        The encoders are absolute within a turn, so nothing moves.
        """
        self._with_torque_off(self._clear_turns)
        return self.position()

    def set_position(self, ring_deg, head_mm):
        """Declare where the machine is (e.g. the journal's last position after a power loss).

        The encoders are exact within a servo turn, so only the ring's turn count
        is taken from the declaration: whole turns are added (Homing Offset) to
        bring it nearest ``ring_deg``.  A head more than 1 mm from ``head_mm`` is
        an error (its single-turn position is absolute).
        """
        head = self.ids["head"]
        here = self.head_mm(self._read(head, "Present Position"))
        if abs(here - head_mm) > 1.0:
            raise self._fail(f"the head servo reads {here:.2f} mm, not the declared {head_mm:.2f} mm; "
                             "its position is absolute: check head_in_ticks/head_out_ticks")
        self._with_torque_off(lambda: self._rebase(ring_deg, False))
        self._remember(ring_deg, head_mm)
        off = self.position()[0] - ring_deg
        if abs(off) > self.machine.pitch_deg / 2:
            log.warning("the ring is %.2f degrees from the declared %.2f: trusting its encoder", off, ring_deg)
        return self.position()

    def _with_torque_off(self, action):
        ring = self.ids["ring"]
        torque = self._read(ring, "Torque Enable")
        if torque:
            self._write(ring, "Torque Enable", 0)
        action()
        if torque:
            self._write(ring, "Torque Enable", 1)
        for servo_id in self.ids.values():
            self.present[servo_id] = self.goal[servo_id] = self._read(servo_id, "Present Position")
        self.position_lost = False

    def unlock(self):
        """Clear hardware errors without moving: reboot the servos that report one (torque off after)."""
        for servo_id in self.ids.values():
            bits = self._read(servo_id, "Hardware Error Status")
            if bits:
                log.warning("%s: %s; rebooting it", self._name(servo_id), ", ".join(dx.hardware_error_names(bits)))
                self.bus.reboot(servo_id)

    def flush(self):
        """Nothing is queued: every goal is waited for."""

    @property
    def lines_sent(self):
        """Instruction packets sent (writes and polls), the analogue of G-code lines."""
        return self.bus.packets + self.bus.polls

    def hold(self):
        """Stop where the servos are (Goal Position := Present Position), torque kept on.

        Returns the :class:`Status` after stopping (``mpos`` = (ring_deg, head_mm)).
        """
        self.bus.drop_input(settle_s=0.02)      # an answer to an interrupted exchange
        for servo_id in self.ids.values():
            try:
                here = self._read(servo_id, "Present Position")
                self._write(servo_id, "Goal Position", here)
                self.present[servo_id] = self.goal[servo_id] = here
            except MachineFailure as exc:
                log.warning("could not stop %s: %s", self._name(servo_id), exc)
        self.state = LinkState.HOLDING
        return self.status()

    def torque_off(self):
        for servo_id in self.ids.values():
            self._write(servo_id, "Torque Enable", 0)

    def close(self):
        """Close the port; the servos keep their torque (the thread stays tensioned)."""
        if self.state is not LinkState.CLOSED:
            try:
                self.bus.close()
            except Exception:  # closing a dead port must not hide the real error
                log.debug("closing the port failed", exc_info=True)
        self.state = LinkState.CLOSED


def open_dynamixel_link(url, machine, **options):
    """The step-level link for a ``kind = "dynamixel"`` machine, its port open (``stringbot.links.open_link``).

    ``options``: ``retries``, ``arrival_slack_s``; others (meant for G-code links) are ignored.
    """
    known = {k: v for k, v in options.items() if k in ("retries", "arrival_slack_s")}
    ignored = sorted(set(options) - set(known))
    if ignored:
        log.debug("Dynamixel link ignores options %s", ", ".join(ignored))
    link = DynamixelLink(machine, url, **known)
    link.open()
    return link
