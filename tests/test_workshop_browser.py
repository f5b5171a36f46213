"""The workshop page driven in headless Chromium: plan a picture, wind it on the simulator, pull the
simulated cable, resume from the page; a spool change answered from the page; the guided way back
with the jog buttons.  The simulator's record judges each; a screenshot of each state is taken
(``STRINGBOT_SCREENSHOTS=docs`` writes them to docs/)."""

import pytest

from bundled import fault_point  # (puts benchmarks/ on the path: matrix_user)
from browser_helpers import Page, browser
from stringbot.planner import read_plan
from stringbot.planner.colour.palette import color_name
from test_workshop_resume import exact, person_answers
from workshop_helpers import EXAMPLES, Server, plan_doc, record, two_colour_picture

pytestmark = pytest.mark.timeout(300)


@pytest.fixture
def page(tmp_path):
    driver = browser()
    server = Server(tmp_path / "plans")
    shots = tmp_path / "shots"
    shots.mkdir()
    try:
        yield Page(driver, server, shots)
    finally:
        driver.quit()
        server.stop()


def plan_on_page(page, picture, **fields):
    page.find("#picture").send_keys(str(picture))
    for key, value in fields.items():
        if key == "machine":
            page.select("#plan-machine", value)
        else:
            page.type(f"#plan-{key}", value)
    page.find("#plan-button").click()
    name = fields.get("name")
    page.wait(lambda: page.finds(f'.plan[data-plan="{name}"] img') and
              page.find(f'.plan[data-plan="{name}"] img').get_attribute("naturalWidth") not in (None, "0"),
              what=f"the plan {name} in the list")
    assert "machine grbl-ring: about" in page.text("#plan-result")


def test_plan_wind_pull_the_cable_resume_from_the_page_the_record_exact(page):
    plan_on_page(page, EXAMPLES / "camera.png", name="cam", machine="grbl-ring", lines="60")
    cli = page.text("#plan-cli")
    assert cli == "stringbot plan pictures/camera.png -o cam.json --machine grbl-ring --lines 60"
    card = page.text('.plan[data-plan="cam"]')
    assert "60 lines" in card and "of winding" in card and "m of thread" in card
    page.shot("plan")
    page.select("#wind-plan", "cam")
    page.type("#wind-faults", "disconnect@150")
    page.wait(lambda: page.text("#wind-cli").startswith("stringbot wind cam.json --machine grbl-ring --port"))
    page.find("#check-button").click()
    page.wait(lambda: "all 9 settings agree with the machine file" in page.text("#wind-result"))
    page.find("#start-button").click()
    q, _ = page.question("grbl-ring")
    assert q["question"].startswith("Tie the thread on at pin")
    page.shot("tie-on")
    page.click_text(page.card("grbl-ring"), "Yes, go on")
    w = page.ended("grbl-ring")
    assert w["outcome"] == "failed" and "lost the connection" in w["line"]
    page.wait(lambda: page.find(page.card("grbl-ring") + " .w-resume").is_displayed())
    page.wait(lambda: not page.find("#resume-button").get_attribute("disabled"))
    assert page.text("#resume-cli").endswith("--journal cam.json.simulator.journal --resume")
    assert f"{w['done']} of 61" in page.text(page.card("grbl-ring") + " .w-step")
    page.shot("interrupted")
    page.find(page.card("grbl-ring") + " .w-resume").click()
    page.server.client.wait("grbl-ring", lambda w: w["resume"])
    q, _ = page.question("grbl-ring")
    assert q["question"].startswith("Resume at pin")
    page.click_text(page.card("grbl-ring"), "Yes, go on")
    w = page.ended("grbl-ring")
    assert w["outcome"] == "finished" and w["check"]["exact"], w
    page.wait(lambda: "wound the plan exactly" in page.text(page.card("grbl-ring") + " .w-check"))
    assert "61 of 61" in page.text(page.card("grbl-ring") + " .w-step")
    page.shot("finished")
    assert exact(page.server.plans, "cam")
    assert page.errors() == []


def test_a_spool_change_answered_from_the_page(page, tmp_path):
    picture = two_colour_picture(tmp_path / "two.png")
    plan_on_page(page, picture, name="two", machine="grbl-ring", lines="80", colors="crimson,navy", spool="1")
    doc = plan_doc(page.server.plans, "two")
    assert len(doc["layers"]) == 2
    page.select("#wind-plan", "two")
    page.find("#start-button").click()
    q, _ = page.question("grbl-ring")                       # the first thread, before the first pin
    assert q["ask"] == "thread" and q["color"] == doc["layers"][0]["color"]
    page.click_text(page.card("grbl-ring"), "Tie it on at the simulator")
    q, _ = page.question("grbl-ring", after=q["id"])
    assert q["ask"] == "thread" and q["question"].startswith("Spool change")
    box = page.text(page.card("grbl-ring") + " .w-question")
    second = doc["layers"][1]                               # the planner chooses the order of the threads
    name = color_name(second["color"])
    assert name in ("crimson", "navy") and name != color_name(doc["layers"][0]["color"])
    assert f"Spool change: tie on {name} at pin {second['sequence'][0]}" in box and "--tie-on" in box
    assert q["name"] == name and second["color"] in box
    page.shot("spool-change")
    page.click_text(page.card("grbl-ring"), "Tie it on at the simulator")
    w = page.ended("grbl-ring")
    assert w["outcome"] == "finished" and w["check"]["exact"], w
    rec = record(page.server.plans)
    assert [(s["color"], s["pin"]) for s in rec["spools"]] == [(lay["color"], lay["sequence"][0]) for lay in doc["layers"]]
    assert page.errors() == []


def test_the_guided_way_back_with_the_jog_buttons(page):
    plan_on_page(page, EXAMPLES / "camera.png", name="cam", machine="grbl-ring", lines="30")
    n = fault_point("grbl-ring", read_plan(page.server.plans / "cam.json"), "hook")
    page.select("#wind-plan", "cam")
    page.type("#wind-faults", f"reboot@{n}+0.5")
    page.find("#start-button").click()
    page.question("grbl-ring")
    page.click_text(page.card("grbl-ring"), "Yes, go on")
    assert page.ended("grbl-ring")["outcome"] == "failed"
    page.find(page.card("grbl-ring") + " .w-resume").click()
    page.server.client.wait("grbl-ring", lambda w: w["resume"])
    op, decide = person_answers(page.server.plans)
    card, shot, jogs, last = page.card("grbl-ring"), False, 0, None
    while True:
        q, w = page.question("grbl-ring", after=last)
        if q is None:
            break
        last = q["id"]
        value = decide(q, w)
        if q["ask"] == "jog":
            if value == "done":
                page.click_text(card, "Done")
                continue
            if not shot:
                assert page.finds(card + " svg.reference"), "the reference is not drawn"
                page.click_text(card + " .jog-row", "+0.1")        # a jog button: then back by typing
                last = page.question("grbl-ring", after=last)[0]["id"]
                page.type(card + " .jog-free input", "ring -0.1")
                page.click_text(card + " .jog-free", "Send")
                page.shot("guide")
                shot = True
                continue
            page.type(card + " .jog-free input", value + "\n")       # Enter sends it
            jogs += 1
        elif q["ask"] == "choose":
            page.click_text(card, value)
        else:
            page.click_text(card, "Yes, go on" if value else "No, stop")
    w = page.server.client.winding("grbl-ring")
    assert shot and jogs >= 1 and w["outcome"] == "finished" and w["check"]["exact"], w
    assert exact(page.server.plans, "cam")
    assert page.errors() == []


@pytest.mark.realtime
def test_the_live_view_while_winding_in_real_time_then_pause(page):
    plan_on_page(page, EXAMPLES / "camera.png", name="cam", machine="grbl-ring", lines="200")
    page.select("#wind-plan", "cam")
    page.find("#wind-realtime").click()
    page.find("#start-button").click()
    page.question("grbl-ring")
    page.click_text(page.card("grbl-ring"), "Yes, go on")
    card = page.card("grbl-ring")
    seen = set()
    page.wait(lambda: seen.add(page.text(card + " .w-step")) or page.server.client.winding("grbl-ring")["done"] >= 8,
              timeout=120)
    assert len(seen) >= 3                                   # the page followed the steps as they came
    w = page.server.client.winding("grbl-ring")
    assert w["phase"] == "running" and w["eta_s"] is not None and w["eta_s"] > 0
    page.wait(lambda: page.text(card + " .w-eta") not in ("", "–"))
    page.shot("winding")
    page.click_text(card, "Pause")
    w = page.ended("grbl-ring")
    assert w["outcome"] == "stopped" and w["stop"]["reason"] == "interrupted", w
    page.wait(lambda: page.find(card + " .w-resume").is_displayed())
    page.shot("paused")
    assert page.errors() == []
