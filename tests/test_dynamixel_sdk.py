"""The unmodified dynamixel_sdk against the emulator on a real pseudo-terminal, and the link on it."""

import logging
import os
import select
import threading
import time
import tty

import dynamixel_sdk as sdk
import pytest

from bundled import PATIENT_GRACE_MS, SERVO_REALTIME
from firmware_protocol import dynamixel as dx
from firmware_protocol.emulators.dynamixel import DynamixelEmulator
from firmware_protocol.machine import load_machine
from firmware_protocol.world import World
from stringbot.errors import BadInput, MachineFailure
from stringbot.links.dynamixel import DynamixelLink

pytestmark = SERVO_REALTIME            # the SDK's answers through a pty, against wall-clock retries


@pytest.fixture(autouse=True)
def patient_servo_link(monkeypatch):
    """The links this module makes wait seconds for a late answer (see bundled.PATIENT_GRACE_MS)."""
    from stringbot.links import dynamixel_bus
    monkeypatch.setattr(dynamixel_bus, "RETRY_GRACE_MS", PATIENT_GRACE_MS)


class PtyServer:
    """Serve an emulator on a pty (fast mode: when the host is quiet, run to the next event;
    realtime: virtual time follows the wall clock)."""

    def __init__(self, emu, idle_s=0.005):
        self.emu, self.idle_s = emu, idle_s
        self.realtime = getattr(emu, "realtime", False)
        self._t0 = time.monotonic()
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self._stop_r, self._stop_w = os.pipe()
        self.lock = threading.Lock()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        while True:
            ready, _, _ = select.select([self.master, self._stop_r], [], [], self.idle_s)
            if self._stop_r in ready:
                return
            with self.lock:
                if self.realtime:
                    self.emu.advance(time.monotonic() - self._t0 - self.emu.now)
                if self.master in ready:
                    self.emu.receive(os.read(self.master, 4096))
                elif self.emu.busy and not self.realtime:
                    self.emu.advance(None)
                out = self.emu.transmit()
            if out:
                os.write(self.master, out)

    def close(self):
        os.write(self._stop_w, b"x")
        self.thread.join(2)
        for fd in (self.master, self.slave, self._stop_r, self._stop_w):
            os.close(fd)


def serve(machine, **kw):
    world = World(machine)
    kw.setdefault("realtime", False)
    emu = DynamixelEmulator(machine, world=world, **kw)
    return PtyServer(emu), emu, world


@pytest.fixture
def machine():
    return load_machine("dynamixel-ring")


@pytest.fixture
def bus(machine, request):
    faults = getattr(request, "param", None)
    server, emu, world = serve(machine, faults=faults)
    yield server, emu, world
    server.close()


def open_sdk(path):
    port = sdk.PortHandler(path)
    assert port.openPort() and port.setBaudRate(1000000)
    return port, sdk.PacketHandler(2.0)


def sdk_call(call, *args):
    """An SDK exchange, repeated (at most 20 times: each waits about 35 ms, the link's own retries
    wait 0.75 s in all) only if a loaded machine made it time out."""
    for _ in range(20):
        out = call(*args)
        result = out[-2] if isinstance(out, tuple) else out
        if result != sdk.COMM_RX_TIMEOUT:
            return out
    return out


def test_sdk_pings_reads_and_writes_through_the_pty(bus):
    server, emu, world = bus
    port, ph = open_sdk(server.path)
    try:
        assert sdk_call(ph.ping, port, 1) == (1020, sdk.COMM_SUCCESS, 0)
        assert ph.ping(port, 9)[1] == sdk.COMM_RX_TIMEOUT
        assert sdk_call(ph.write1ByteTxRx, port, 1, 11, 4) == (sdk.COMM_SUCCESS, 0)
        assert sdk_call(ph.write1ByteTxRx, port, 1, 64, 1) == (sdk.COMM_SUCCESS, 0)
        assert sdk_call(ph.write4ByteTxRx, port, 1, 116, 2 * 4096) == (sdk.COMM_SUCCESS, 0)
        moving = 1
        while moving:
            moving, result, _ = sdk_call(ph.read1ByteTxRx, port, 1, 122)
            assert result == sdk.COMM_SUCCESS
        assert sdk_call(ph.read4ByteTxRx, port, 1, 132) == (2 * 4096, sdk.COMM_SUCCESS, 0)
        assert world.ring_deg == pytest.approx(180.0)
        # a refused write comes back with its error number
        assert sdk_call(ph.write1ByteTxRx, port, 1, 11, 3) == (sdk.COMM_SUCCESS, 0x07)   # EEPROM, torque on
        group = sdk.GroupSyncRead(port, ph, 132, 4)
        group.addParam(1)
        group.addParam(2)
        assert sdk_call(group.txRxPacket) == sdk.COMM_SUCCESS
        assert (group.getData(1, 132, 4), group.getData(2, 132, 4)) == (8192, 1800)
    finally:
        port.closePort()


def link_on(server, machine, **kw):
    link = DynamixelLink(machine, server.path, **kw)
    link.connect()
    return link


def test_link_connects_checks_models_and_prepares(bus, machine):
    server, emu, world = bus
    link = link_on(server, machine)
    try:
        assert [(s.role, s.id, s.model_name) for s in link.servos.values()] == [
            ("ring", 1, "XM430-W350"), ("head", 2, "XM430-W350")]
        assert link.prepare() == (0.0, 0.0)
        assert emu.ring.get("Operating Mode") == dx.OperatingMode.EXTENDED_POSITION
        assert emu.head.get("Operating Mode") == dx.OperatingMode.POSITION
        assert emu.ring.get("Profile Velocity") == machine["controller.profile_velocity"]
        assert emu.ring.get("Torque Enable") == emu.head.get("Torque Enable") == 1
        link.move_to(450.0, 12.0)                  # 1.25 ring turns = 5 servo turns, head out
        assert (world.ring_deg, world.head_mm) == (pytest.approx(450.0), pytest.approx(12.0))
        assert link.position() == (pytest.approx(450.0, abs=0.01), pytest.approx(12.0, abs=0.03))
    finally:
        link.close()


def test_wrong_model_is_named(machine, tmp_path):
    text = machine.path and open(machine.path).read().replace("model_number = 1020", "model_number = 1060")
    path = tmp_path / "m.toml"
    path.write_text(text)
    other = load_machine(path)
    server, emu, world = serve(machine)
    try:
        with pytest.raises(MachineFailure, match=r"ring servo \(id 1\) is a XM430-W350 .*1060 \(XL430-W250\)"):
            link_on(server, other)
    finally:
        server.close()


def test_travel_beyond_the_extended_range_is_bad_input(machine):
    values = dict(machine.values)
    values["ring.travel_deg"] = 30000.0                     # 30000 deg * 4 = 333 servo turns
    with pytest.raises(BadInput, match=r"ring.travel_deg = 30000 .*expected ring.travel_deg <= 22949 "):
        DynamixelLink(type(machine)(machine.name, machine.path, values), "/dev/null")


def test_ring_goal_outside_the_extended_range_fails_before_sending(bus, machine):
    server, emu, world = bus
    link = link_on(server, machine)
    try:
        link.prepare()
        with pytest.raises(MachineFailure, match="outside the servo's extended-position range"):
            link.move_to(24000.0, 0.0)
        assert emu.ring.motion is None and world.ring_deg == 0.0
    finally:
        link.close()


@pytest.mark.parametrize("bus", ["hardware_error@move=1:id=1:bits=0x20"], indirect=True)
def test_hardware_error_is_reported_by_name(bus, machine):
    server, emu, world = bus
    link = link_on(server, machine)
    try:
        link.prepare()
        link.where = (4, 17)
        with pytest.raises(MachineFailure, match=r"ring servo \(id 1\) reports a hardware error: "
                                                 r"Overload Error.*\(at pin 17, step 4\)"):
            link.move_to(90.0, 0.0)
        link.prepare(resume_at=link.position())               # reboots it and goes on
        link.move_to(90.0, 0.0)
        assert world.ring_deg == pytest.approx(90.0)
    finally:
        link.close()


@pytest.mark.parametrize("bus", ["silent@move=1:id=2"], indirect=True)
def test_servo_that_stops_answering_is_a_clear_failure(bus, machine):
    server, emu, world = bus
    link = link_on(server, machine, retries=1)
    try:
        link.prepare()
        with pytest.raises(MachineFailure, match=r"head servo \(id 2\) failed polling its position: "
                                                 r"COMM_RX_TIMEOUT after 2 attempts; it does not answer"):
            link.move_to(0.0, 12.0)
    finally:
        link.close()


@pytest.mark.parametrize("bus", ["corrupt@packet=20"], indirect=True)
def test_corrupted_answer_is_retried(bus, machine, caplog):
    server, emu, world = bus
    caplog.set_level(logging.INFO, logger="stringbot.links.dynamixel_bus")   # a first failure is INFO
    link = link_on(server, machine)
    try:
        link.prepare()
        link.move_to(30.0, 12.0)
        link.move_to(30.0, 0.0)
        assert link.retried >= 1 and "COMM_RX_CORRUPT" in caplog.text
        assert any("corrupt status packet 20" in text for _, text in emu.log)
        assert (world.ring_deg, world.head_mm) == (pytest.approx(30.0, abs=0.01), pytest.approx(0.0))
    finally:
        link.close()


@pytest.mark.parametrize("bus", ["power_loss@move=3"], indirect=True)
def test_power_loss_then_resume_rebases_the_ring_exactly(bus, machine):
    server, emu, world = bus
    link = link_on(server, machine)
    try:
        link.prepare()
        link.move_to(720.0, 0.0)                                 # 2 ring turns = 8 servo turns
        link.move_to(720.0, 12.0)
        with pytest.raises(MachineFailure, match=r"lost torque \(power loss or reboot\?\)"):
            link.move_to(730.0, 12.0)                            # power lost halfway
        assert world.ring_deg == pytest.approx(725.0, abs=0.5)
        hint = link.position()
    finally:
        link.close()
    link = link_on(server, machine)                              # a new process resumes
    try:
        ring_deg, head_mm = link.prepare(resume_at=hint)
        assert ring_deg == pytest.approx(world.ring_deg, abs=360 / (4 * 4096))   # to the tick
        assert head_mm == pytest.approx(world.head_mm, abs=0.03)
        assert emu.ring.get("Homing Offset") == 8 * 4096         # whole turns added back
        link.move_to(730.0, 12.0)
        link.move_to(730.0, 0.0)
        assert (world.ring_deg, world.head_mm) == (pytest.approx(730.0, abs=0.01), pytest.approx(0.0))
    finally:
        link.close()


def test_profile_velocity_above_the_velocity_limit_is_bad_input(machine):
    values = dict(machine.values)
    values["controller.profile_velocity"] = 300
    strict = type(machine)(machine.name, machine.path, values)
    server, emu, world = serve(machine)
    try:
        link = link_on(server, strict)
        with pytest.raises(BadInput, match=r"controller.profile_velocity = 300 exceeds .*Velocity Limit \(44\) = 128"):
            link.prepare()
        link.close()
    finally:
        server.close()


@pytest.mark.parametrize("bus", ["hardware@1:id=2:bits=0x04"], indirect=True)
def test_unlock_set_position_and_home(bus, machine):
    server, emu, world = bus
    link = link_on(server, machine)
    try:
        link.prepare()
        with pytest.raises(MachineFailure, match=r"head servo \(id 2\) reports a hardware error: Overheating Error"):
            link.move_to(0.0, 12.0)
        link.unlock()
        assert emu.head.get("Hardware Error Status") == 0 and emu.head.get("Torque Enable") == 0
        link.prepare(resume_at=link.position())
        # a declaration sets the turn count only: the encoder is exact within a turn
        assert link.set_position(720.4, link.position()[1])[0] == pytest.approx(720.0, abs=0.03)
        assert emu.ring.get("Torque Enable") == 1 and emu.ring.get("Homing Offset") == 8 * 4096
        link.move_to(730.0, 0.0)                                 # 10 degrees on from the declared place
        assert world.ring_deg == pytest.approx(10.0, abs=0.03)
        with pytest.raises(MachineFailure, match="head servo reads"):
            link.set_position(0.0, 12.0)
        assert link.home()[0] == pytest.approx(10.0, abs=0.03)   # turn count cleared; nothing moved
        assert emu.ring.get("Homing Offset") == 0 and world.ring_deg == pytest.approx(10.0, abs=0.03)
    finally:
        link.close()


def test_realtime_mode_takes_the_profile_time(machine):
    """The move takes its profile time on the emulator's clock, which in realtime mode never runs
    ahead of the wall clock (no timed assert; figures: benchmarks/bench_realtime.py)."""
    wall0 = time.monotonic()                            # before the server (its clock follows from here)
    server, emu, world = serve(machine, realtime=True)
    link = link_on(server, machine)
    try:
        link.prepare()
        v = 120 * 0.229 / 60 * 4096                     # ticks/s at Profile Velocity 120
        a = 80 * 214.577 / 3600 * 4096                  # ticks/s^2 at Profile Acceleration 80
        ticks = link.ring_ticks(45.0)                   # half a servo turn: 2048 ticks
        expected = ticks / v + v / a
        with server.lock:
            start = emu.now
        link.move_to(45.0, 0.0)
        with server.lock:
            assert emu.now - start >= 0.99 * expected
            assert emu.now <= time.monotonic() - wall0
        assert world.ring_deg == pytest.approx(45.0, abs=0.03)
    finally:
        link.close()
        server.close()
