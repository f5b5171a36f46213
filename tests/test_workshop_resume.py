"""The workshop's ways back: the guided resume answered from the page (jog, done), Pause then
Resume, and the server itself killed mid-winding; the simulator's record judges each."""

import json
import signal
import time

import pytest

from bundled import fault_point  # (puts benchmarks/ on the path: matrix_user)
from matrix_user import _operator
from stringbot.planner import read_plan
from workshop_helpers import EXAMPLES, Server, alive, plan_doc, record, yes

pytestmark = pytest.mark.timeout(300)


@pytest.fixture
def plans(tmp_path):
    return tmp_path / "plans"


@pytest.fixture
def server(plans):
    srv = Server(plans)
    yield srv
    srv.stop()


def exact(plans, name):
    rec = record(plans)
    return [x["pin"] for x in rec["wraps"]] == plan_doc(plans, name)["sequence"] and rec["collisions"] == []


def person_answers(plans, machine="grbl-ring"):
    """A person at the simulator who answers the page's questions by looking at the machine (the
    simulator's record), jogging it to the reference the guide names (tests/scripted_operator.py)."""
    op = _operator(machine, plans / "simulator" / f"{machine}-record.json")
    heard = {"n": 0}

    def answer(q, w):
        # the simulator writes its record once it stands idle, as the host asks its next question:
        # a person looks a moment later (as benchmarks/matrix_user.py waits for a quiet terminal)
        time.sleep(0.2)
        new = w["said_count"] - heard["n"]
        for text in (w["said"][-new:] if new > 0 else []):
            op.say(text)
        heard["n"] = w["said_count"]
        if q["ask"] == "jog":
            return op.jog(q["prompt"])
        if q["ask"] == "choose":
            return op.choose(q["question"], q["choices"])
        return op.confirm(q["question"])
    return op, answer


def test_a_reboot_mid_hook_is_resumed_by_the_guide_answered_from_the_page(server, plans):
    c = server.client
    c.plan(EXAMPLES / "camera.png", name="cam", machine="grbl-ring", lines="30")
    n = fault_point("grbl-ring", read_plan(plans / "cam.json"), "hook")
    c.post("/api/wind", {"plan": "cam", "machine": "grbl-ring", "target": "simulator", "faults": f"reboot@{n}+0.5"})
    w, _ = c.run("grbl-ring", yes)
    assert w["outcome"] == "failed", w
    op, answer = person_answers(plans)
    c.post("/api/wind", {"plan": "cam", "machine": "grbl-ring", "target": "simulator", "resume": True})
    w, asked = c.run("grbl-ring", answer)
    kinds = [q["ask"] for q in asked]
    assert "jog" in kinds, asked                 # the guided way, from the page
    assert op.jogs and any(j.startswith("ring") for j in op.jogs)
    assert asked[kinds.index("jog") - 1]["ask"] in ("choose", "confirm")
    assert any("facing the head station" in s for s in op.told)
    assert w["outcome"] == "finished" and w["check"]["exact"], w
    assert exact(plans, "cam")


@pytest.mark.realtime
def test_pause_holds_the_feed_journaled_and_resume_continues_exactly(server, plans):
    c = server.client
    c.plan(EXAMPLES / "camera.png", name="cam", machine="grbl-ring", lines="8")
    c.post("/api/wind", {"plan": "cam", "machine": "grbl-ring", "target": "simulator", "realtime": True})
    w = c.wait("grbl-ring", lambda w: w["phase"] == "asking")
    c.post("/api/windings/grbl-ring/answer", {"id": w["question"]["id"], "value": True})
    c.wait("grbl-ring", lambda w: w["done"] >= 3, timeout=120)
    c.post("/api/windings/grbl-ring/stop")
    w = c.wait("grbl-ring", lambda w: w["phase"] == "ended", timeout=60)
    assert w["outcome"] == "stopped" and w["code"] == 130 and w["done"] < 9, w
    assert "interrupted at pin" in w["line"] and w["line"].endswith("--resume")
    assert w["stop"]["reason"] == "interrupted"
    c.post("/api/wind", {"plan": "cam", "machine": "grbl-ring", "target": "simulator", "resume": True})
    w, asked = c.run("grbl-ring", yes)
    assert asked[0]["question"].startswith("Resume at pin") and w["outcome"] == "finished", w
    assert w["check"]["exact"] and exact(plans, "cam")


@pytest.mark.realtime
def test_the_server_killed_mid_winding_loses_nothing(plans):
    srv = Server(plans)
    try:
        c = srv.client
        c.plan(EXAMPLES / "camera.png", name="cam", machine="grbl-ring", lines="8")
        c.post("/api/wind", {"plan": "cam", "machine": "grbl-ring", "target": "simulator", "realtime": True})
        w = c.wait("grbl-ring", lambda w: w["phase"] == "asking")
        c.post("/api/windings/grbl-ring/answer", {"id": w["question"]["id"], "value": True})
        w = c.wait("grbl-ring", lambda w: w["done"] >= 3, timeout=120)
        child, sim = w["pid"], c.get("/api/state")["simulators"]["grbl-ring"]["pid"]
        srv.proc.kill()                             # the server's crash
        srv.proc.wait()
        deadline = time.monotonic() + 60
        while alive(child) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not alive(child), "the winding did not stop when its server died"
    finally:
        srv.stop()
    journal = [json.loads(x) for x in (plans / "cam.json.simulator.journal").read_text().splitlines()]
    assert journal[-1]["kind"] == "stop" and journal[-1]["reason"] == "interrupted"     # the Ctrl-C way
    assert alive(sim)                               # the simulated machine still serves: adopted next
    again = Server(plans)
    try:
        c = again.client
        assert c.get("/api/state")["simulators"]["grbl-ring"]["pid"] == sim
        assert c.get("/api/plans/cam")["journals"]["simulator"]["resumable"]
        c.post("/api/wind", {"plan": "cam", "machine": "grbl-ring", "target": "simulator", "resume": True})
        w, asked = c.run("grbl-ring", yes)
        assert w["outcome"] == "finished" and w["check"]["exact"], w
        assert exact(plans, "cam")
    finally:
        assert again.stop(signal.SIGTERM) == 0
    assert not alive(sim)                           # the workshop's end ends its simulators
