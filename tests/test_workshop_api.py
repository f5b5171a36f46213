"""``stringbot serve`` through its HTTP API: plan, wind on the simulator, a pulled cable and the
resume, a spool change, a busy machine, bad input; the simulator's record judges every winding."""

import json
import socket
import subprocess

import pytest

from workshop_helpers import EXAMPLES, STRINGBOT, HttpError, Server, plan_doc, record, sequence, two_colour_picture, \
    yes

pytestmark = pytest.mark.timeout(300)


@pytest.fixture
def server(tmp_path):
    srv = Server(tmp_path / "plans")
    yield srv
    srv.stop()


def small_plan(client, name="cam", lines=40):
    return client.plan(EXAMPLES / "camera.png", name=name, machine="grbl-ring", lines=str(lines))


def test_plan_writes_the_plan_and_preview_and_shows_the_command_and_estimates(server):
    c = server.client
    r = small_plan(c)
    assert r["command"] == "stringbot plan pictures/camera.png -o cam.json --machine grbl-ring --lines 40"
    assert (server.plans / "cam.json").is_file() and (server.plans / "cam.png").is_file()
    assert (server.plans / "pictures" / "camera.png").read_bytes() == (EXAMPLES / "camera.png").read_bytes()
    info = r["plan"]
    assert info["lines"] == 40 and info["steps"] == 41 and info["machine"] == "grbl-ring"
    assert info["estimate"]["machine"] == "grbl-ring" and info["estimate"]["thread_m"] > 1
    assert any("machine grbl-ring: about" in line for line in r["said"])     # what the command printed
    assert [p["name"] for p in c.get("/api/plans")["plans"]] == ["cam"]
    drawing = c.get("/api/plans/cam/drawing")
    assert drawing["layers"][0]["sequence"] == plan_doc(server.plans, "cam")["sequence"]
    # the same picture again is the same file; the plan's command line names it
    again = c.plan(EXAMPLES / "camera.png", name="cam2", lines="30")
    assert again["command"].startswith("stringbot plan pictures/camera.png -o cam2.json")
    assert sorted(p.name for p in (server.plans / "pictures").iterdir()) == ["camera.png"]


@pytest.mark.parametrize("fields, upload, says", [
    ({"lines": "0"}, None, "--lines 0; expected a positive number or auto"),
    ({"machine": "no-such-ring"}, None, "unknown machine 'no-such-ring'; expected one of: "),
    ({"pins": "2", "machine": ""}, None, "--pins 2; expected 3..802"),
    ({"name": "../evil"}, None, "plan name '../evil'; expected letters, digits"),
    ({}, ("notes.png", b"not a picture at all"), "picture 'pictures/notes.png' is not a picture PIL can read"),
    ({}, ("empty.png", b""), "picture 'empty.png' is an empty file (0 bytes)"),
])
def test_bad_plan_input_is_400_with_the_command_lines_own_line_and_nothing_kept(server, fields, upload, says):
    c = server.client
    small_plan(c)
    before = sorted(p.relative_to(server.plans) for p in server.plans.rglob("*"))
    name, data = upload or ("camera.png", (EXAMPLES / "camera.png").read_bytes())
    with pytest.raises(HttpError) as info:
        c.upload("/api/plans", {"name": "cam", "machine": "grbl-ring", **fields}, "picture", name, data)
    assert info.value.status == 400
    error = info.value.body["error"]
    assert says in error and "\n" not in error and "Traceback" not in error
    assert sorted(p.relative_to(server.plans) for p in server.plans.rglob("*")) == before   # nothing on disk


def test_bad_wind_input_and_missing_plan_are_400(server):
    c = server.client
    small_plan(c)
    for body, says in [({"plan": "nope", "machine": "grbl-ring"}, "plan 'nope' is not in the plans folder"),
                       ({"plan": "cam", "machine": "mill"}, "unknown machine 'mill'"),
                       ({"plan": "cam", "machine": "grbl-ring", "target": "moon"}, "target 'moon'; expected one of"),
                       ({"plan": "cam", "machine": "grbl-ring", "target": "port"}, "port is empty"),
                       ({"plan": "cam", "machine": "grbl-ring", "faults": "bogus@1"},
                        "--faults 'bogus@1': bad fault 'bogus@1'; expected a comma list of")]:
        with pytest.raises(HttpError) as info:
            c.post("/api/wind", body)
        assert info.value.status == 400 and says in info.value.body["error"], info.value.body
    import urllib.request
    req = urllib.request.Request(server.url + "/api/wind", data=b"{not json", method="POST",
                                 headers={"Content-Type": "application/json"})
    with pytest.raises(HttpError) as info:
        c._open(req)
    assert info.value.status == 400 and "not JSON" in info.value.body["error"]
    # the command line's own refusal of a port that is not there: the winding ends, exit 2, its line
    c.post("/api/wind", {"plan": "cam", "machine": "grbl-ring", "target": "port", "port": "/dev/ttyNOPE"})
    w = c.wait("grbl-ring", lambda w: w["phase"] == "ended")
    assert w["code"] == 2 and w["line"] == ("stringbot: error: port '/dev/ttyNOPE' does not exist; give --port a "
                                            "serial device (e.g. /dev/ttyUSB0, COM3) or a URL (socket://host:port, sim://)")


def test_a_pulled_cable_then_resume_from_the_page_winds_the_plan_exactly(server):
    c = server.client
    small_plan(c)
    start = c.post("/api/wind", {"plan": "cam", "machine": "grbl-ring", "target": "simulator",
                                 "faults": "disconnect@100"})
    assert start["command"] == ("stringbot wind cam.json --machine grbl-ring --port simulator/grbl-ring.pty "
                                "--journal cam.json.simulator.journal")
    w, asked = c.run("grbl-ring", yes)
    assert asked[0]["question"].startswith("Tie the thread on at pin ")
    assert w["outcome"] == "failed" and w["code"] == 1
    assert "lost the connection to the machine" in w["line"] and w["line"].endswith(
        "resume with: stringbot wind cam.json --machine grbl-ring --port simulator/grbl-ring.pty --journal "
        "cam.json.simulator.journal --resume")
    assert 0 < w["done"] < 41 and w["stop"]["reason"] == "failed"
    journal = c.get("/api/plans/cam")["journals"]["simulator"]
    assert journal["resumable"] and journal["done"] == w["done"]
    # a second start would lose the winding: refused, naming Resume
    with pytest.raises(HttpError) as info:
        c.post("/api/wind", {"plan": "cam", "machine": "grbl-ring", "target": "simulator"})
    assert info.value.status == 400 and "continue it with Resume" in info.value.body["error"]
    c.post("/api/wind", {"plan": "cam", "machine": "grbl-ring", "target": "simulator", "resume": True})
    w, asked = c.run("grbl-ring", yes)
    assert asked and asked[0]["question"].startswith("Resume at pin "), w
    assert w["outcome"] == "finished" and w["done"] == 41, w
    rec = record(server.plans)
    assert [x["pin"] for x in rec["wraps"]] == plan_doc(server.plans, "cam")["sequence"]
    assert rec["collisions"] == []
    assert w["check"]["exact"] and "wound the plan exactly: 41 wraps" in w["check"]["text"]


def test_a_spool_change_is_answered_from_the_page_and_every_run_has_its_colour(server, tmp_path):
    c = server.client
    c.upload("/api/plans", {"name": "two", "machine": "grbl-ring", "lines": "80", "colors": "crimson,navy",
                            "spool_changes": "1", "min_run": "20"}, "picture", "two.png",
             two_colour_picture(tmp_path / "two.png").read_bytes())
    doc = plan_doc(server.plans, "two")
    assert len(doc["layers"]) == 2
    c.post("/api/wind", {"plan": "two", "machine": "grbl-ring", "target": "simulator"})
    w, asked = c.run("grbl-ring", yes)
    threads = [q for q in asked if q["ask"] == "thread"]
    second = doc["layers"][1]
    assert [q["color"] for q in threads] == [lay["color"] for lay in doc["layers"]]
    assert threads[1]["question"].startswith("Spool change: cut the ")
    assert threads[1]["pin"] == second["sequence"][0] and f"at pin {second['sequence'][0]}" in threads[1]["question"]
    assert w["outcome"] == "finished" and w["check"]["exact"], w
    rec = record(server.plans)
    assert [x["pin"] for x in rec["wraps"]] == sequence(doc) and rec["collisions"] == []
    starts = [0, len(doc["layers"][0]["sequence"])]
    assert [x["color"] for x in rec["wraps"][starts[0]:starts[1]]] == [doc["layers"][0]["color"]] * starts[1]
    assert {x["color"] for x in rec["wraps"][starts[1]:]} == {second["color"]}
    assert [(s["color"], s["pin"]) for s in rec["spools"]] == [(lay["color"], lay["sequence"][0]) for lay in doc["layers"]]


def test_declining_a_spool_change_stops_journaled_and_resume_asks_for_that_thread_again(server, tmp_path):
    c = server.client
    c.upload("/api/plans", {"name": "two", "machine": "grbl-ring", "lines": "80", "colors": "crimson,navy",
                            "spool_changes": "1", "min_run": "20"}, "picture", "two.png",
             two_colour_picture(tmp_path / "two.png").read_bytes())
    c.post("/api/wind", {"plan": "two", "machine": "grbl-ring", "target": "simulator"})
    w, asked = c.run("grbl-ring", lambda q, w: not q["question"].startswith("Spool change"))
    assert w["outcome"] == "stopped" and w["code"] == 130 and "spool change before step" in w["line"]
    c.post("/api/wind", {"plan": "two", "machine": "grbl-ring", "target": "simulator", "resume": True})
    w, asked = c.run("grbl-ring", yes)
    assert sum(q["ask"] == "thread" for q in asked) == 1 and w["outcome"] == "finished" and w["check"]["exact"], w


def test_one_winding_per_machine_and_a_second_client_sees_the_same_state(server):
    c = server.client
    small_plan(c)
    c.post("/api/wind", {"plan": "cam", "machine": "grbl-ring", "target": "simulator"})
    w = c.wait("grbl-ring", lambda w: w["phase"] == "asking")        # waits for the tie-on
    with pytest.raises(HttpError) as info:
        c.post("/api/wind", {"plan": "cam", "machine": "grbl-ring", "target": "dry-run"})
    assert info.value.status == 409 and "one winding per machine" in info.value.body["error"]
    other = type(c)(server.url)                                      # another browser
    assert other.get("/api/state")["windings"]["grbl-ring"]["question"] == w["question"]
    c.post("/api/windings/grbl-ring/answer", {"id": w["question"]["id"], "value": True})
    with pytest.raises(HttpError) as info:                           # answered already, on the first page
        other.post("/api/windings/grbl-ring/answer", {"id": w["question"]["id"], "value": False})
    assert info.value.status == 409
    w = c.wait("grbl-ring", lambda w: w["phase"] == "ended")
    assert w["outcome"] == "finished" and w["check"]["exact"]
    # another machine meanwhile: its own winding (a dry run, its own record check)
    c.post("/api/wind", {"plan": "cam", "machine": "grbl-ring", "target": "dry-run"})
    w, _ = c.run("grbl-ring", yes)
    assert w["outcome"] == "finished" and w["command"].endswith("--record cam.dry-run-record.json")


def test_the_event_stream_pushes_the_state(server):
    import urllib.request

    c = server.client
    small_plan(c)
    c.post("/api/wind", {"plan": "cam", "machine": "grbl-ring", "target": "dry-run"})
    with urllib.request.urlopen(server.url + "/api/events", timeout=30) as stream:
        states = []
        for raw in stream:
            line = raw.decode().strip()
            if line.startswith("data: "):
                states.append(json.loads(line[6:]))
                w = states[-1]["windings"].get("grbl-ring")
                if w and w["phase"] == "asking":
                    c.post("/api/windings/grbl-ring/answer", {"id": w["question"]["id"], "value": True})
                if w and w["phase"] == "ended":
                    break
    assert states[-1]["windings"]["grbl-ring"]["done"] == 41
    assert len(states) >= 2


def test_serve_refuses_a_port_in_use_and_a_bad_host_in_one_line(tmp_path):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        p = subprocess.run(STRINGBOT + ["serve", "--port", str(port), "--plans", str(tmp_path / "p")],
                           capture_output=True, text=True, timeout=60)
    assert p.returncode == 2 and p.stderr.strip().splitlines() == [
        f"stringbot: error: --port {port}: the address 127.0.0.1:{port} is in use (another server listens there); "
        "expected a free port, e.g. --port 8001"]
    p = subprocess.run(STRINGBOT + ["serve", "--host", "no-such-host.invalid", "--plans", str(tmp_path / "p")],
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1 and "--host 'no-such-host.invalid'" in p.stderr
    (tmp_path / "afile").write_text("mine")
    p = subprocess.run(STRINGBOT + ["serve", "--plans", str(tmp_path / "afile")], capture_output=True, text=True,
                       timeout=60)
    assert p.returncode == 2 and "is a file; expected a folder" in p.stderr and (tmp_path / "afile").read_text() == "mine"
