"""What the Dynamixel winding tests share: their plans, the machine, a patient link, a resume by hand, and
``stringbot`` in its own process (`simulate` serving the bus on a pty, `wind` on it)."""

import numpy as np
import pytest

from bundled import PATIENT_GRACE_MS
from firmware_protocol.machine import load_machine
from stringbot.links.dynamixel import DynamixelLink


@pytest.fixture
def patient_servo_link(monkeypatch):
    """The links this module makes wait seconds for a late answer (see bundled.PATIENT_GRACE_MS)."""
    from stringbot.links import dynamixel_bus
    monkeypatch.setattr(dynamixel_bus, "RETRY_GRACE_MS", PATIENT_GRACE_MS)


def random_sequence(n, pins=300, seed=3):
    rng = np.random.default_rng(seed)
    seq = [int(rng.integers(pins))]
    while len(seq) < n:
        p = int(rng.integers(pins))
        if p != seq[-1]:
            seq.append(p)
    return seq


PLANS = {
    "long jumps": [0, 150, 1, 151, 2, 152, 299, 149, 75, 225],
    "seam": [0, 299, 1, 298, 0, 299, 0, 1, 299],
    "one way round": [0, 100, 200] * 6 + [0],
    "random": random_sequence(40),
}


@pytest.fixture
def machine():
    return load_machine("dynamixel-ring")


def resume(server, machine, steps, stop, declare=False):
    """What a resume does: a new link, re-base, the rest of the stopped step, the other steps.

    ``declare``: the generic way of the wind loop: prepare, see the position lost, declare it."""
    link = DynamixelLink(machine, server.path)
    try:
        link.identify()
        if declare:
            link.prepare()
            assert link.position_lost
            link.set_position(*stop["position"])
        else:
            link.prepare(resume_at=stop["position"])
        i, k = stop["step_index"], stop["move"]
        link.execute_lines(steps[i], steps[i].moves[k:])
        link.execute(steps[i + 1:])
        return link.position()
    finally:
        link.close()


def _simulate(tmp_path, *args):
    """`stringbot simulate --machine dynamixel-ring --pty PATH ...` in its own process."""
    import os
    import subprocess
    import sys
    import time

    pty = tmp_path / "dxl"
    sim = subprocess.Popen([sys.executable, "-c", "from stringbot.cli import main; main()", "simulate",
                            "--machine", "dynamixel-ring", "--pty", str(pty), *args],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    for _ in range(200):
        if os.path.islink(pty):
            break
        time.sleep(0.05)
    return sim, str(pty)


def _stop(sim):
    import signal
    sim.send_signal(signal.SIGINT)
    return sim.communicate(timeout=10)


def _stringbot(*args):
    import subprocess
    import sys
    return subprocess.run([sys.executable, "-c", "from stringbot.cli import main; main()", *args],
                          capture_output=True, text=True, timeout=120)

