"""Winding by hand, the library (stringbot.winding.by_hand): the steps, the saved position, the pace."""

import json

import pytest

from stringbot.errors import BadInput
from stringbot.motion.pins import pin_list, thread_metres
from stringbot.planner.plan_file import write_plan
from stringbot.winding.by_hand import (BREAK_S, ETA_AFTER, PACE_WINDOW, PACES_KEPT, HandWinding, Phase,
                                       position_path_for, read_position)
from test_colour_plan import colour_plan
from test_gcode_replay import make_plan, random_sequence


@pytest.fixture
def plan_path(tmp_path):
    path = tmp_path / "p.json"
    plan = make_plan(random_sequence(40, seed=7))
    plan.diameter_mm, plan.thread_mm = 500.0, 0.25
    write_plan(plan, path)
    return path


def opened(path, **kw):
    from stringbot.planner.plan_file import read_plan
    plan = read_plan(path)
    return HandWinding.open(plan, plan_path=str(path), size_mm=kw.pop("size_mm", 500.0), **kw)


def test_the_steps_are_the_pin_lists_rows(plan_path):
    hw, how = opened(plan_path)
    assert how == "new" and hw.done == 0 and hw.phase is Phase.WINDING
    rows = pin_list(hw.plan).rows
    assert [(s.number, s.pin, s.plan_pin, s.wrap) for s in hw.steps] == [tuple(r) for r in rows]
    assert [s.pin for s in hw.steps] == hw.plan.sequence
    assert hw.steps[0].tie_on == f"tie the thread on at pin {hw.plan.sequence[0]}"
    assert all(s.tie_on is None for s in hw.steps[1:])
    assert [s.next_pin for s in hw.steps] == hw.plan.sequence[1:] + [None]


def test_next_back_go_save_the_position_every_time(plan_path):
    hw, _ = opened(plan_path)
    saved = position_path_for(plan_path)
    hw.save()
    for k in range(1, 6):
        assert hw.next(now=10.0 * k)
        assert read_position(saved).done == k
    assert hw.back(now=60.0) and read_position(saved).done == 4
    assert hw.current.pin == hw.plan.sequence[4]
    hw.go(40, now=61.0)
    assert read_position(saved).done == 39 and hw.current.number == 40
    with pytest.raises(BadInput, match=r"step 41; expected a step 1\.\.40"):
        hw.go(41, now=62.0)
    assert hw.next(now=70.0) and hw.phase is Phase.FINISHED and hw.current is None
    assert not hw.next(now=71.0)
    doc = json.loads(open(saved).read())
    assert doc["done"] == 40 and doc["next_pin"] is None and doc["plan_sha256"] == hw.plan.sha256()
    hw.go(1, now=72.0)
    assert not hw.back(now=73.0) and hw.done == 0


def test_a_new_session_resumes_where_the_last_one_stopped_with_its_pace(plan_path):
    hw, _ = opened(plan_path)
    hw.shown(0.0)
    for k in range(1, 8):
        hw.next(now=4.0 * k)
    again, how = opened(plan_path)
    assert how == "resumed" and again.done == 7 and again.paces == [4.0] * 7
    assert again.current.pin == again.plan.sequence[7]
    restarted, how = opened(plan_path, restart=True)
    assert how == "restarted" and restarted.done == 0 and restarted.paces == [4.0] * 7
    there, how = opened(plan_path, from_step=30)
    assert how == "from step" and there.current.number == 30


def test_the_eta_is_the_median_of_the_recent_paces_times_the_steps_left(plan_path):
    hw, _ = opened(plan_path)
    hw.shown(0.0)
    t = 0.0
    for k, pace in enumerate([5.0, 3.0]):
        t += pace
        hw.next(now=t)
        assert hw.progress().eta_s is None          # not before ETA_AFTER steps are timed
    assert ETA_AFTER == 3
    for pace in [4.0, BREAK_S + 1, 0.05, 100.0, 2.0]:     # a break and a skip are not the pace
        t += pace
        hw.next(now=t)
    assert hw.paces == [5.0, 3.0, 4.0, 100.0, 2.0]
    p = hw.progress()
    assert p.pace_s == 4.0 and p.eta_s == 4.0 * (40 - 7) and p.done == 7 and p.total == 40
    assert p.percent == pytest.approx(100 * 7 / 40)
    for _ in range(PACE_WINDOW):
        t += 1.0
        hw.next(now=t)
    assert hw.progress().pace_s == 1.0              # only the recent ones count
    assert len(hw.paces) <= PACES_KEPT


def test_thread_to_go_counts_from_the_chord_into_the_pin_shown(plan_path):
    hw, _ = opened(plan_path)
    seq = hw.plan.sequence
    assert hw.progress().thread_left_m == pytest.approx(thread_metres(hw.plan, 500.0))
    hw.go(10, now=0.0)
    assert hw.progress().thread_left_m == pytest.approx(thread_metres(hw.plan, 500.0, seq[8:]))
    no_size, _ = opened(plan_path, size_mm=None)
    assert no_size.progress().thread_left_m is None


def test_a_position_for_another_plan_is_refused(plan_path, tmp_path):
    hw, _ = opened(plan_path)
    hw.go(12, now=0.0)
    other = make_plan(random_sequence(40, seed=8))
    write_plan(other, plan_path)                     # planned again under the same name
    with pytest.raises(BadInput) as info:
        opened(plan_path)
    msg = str(info.value)
    assert "is for another plan" in msg and "step 12 of 40" in msg and "--restart" in msg
    assert read_position(position_path_for(plan_path)).done == 11      # left as it was
    hw2, how = opened(plan_path, from_step=3)
    assert how == "from step" and hw2.paces == []


@pytest.mark.parametrize("kw, words", [({"from_step": 0}, "--from-step 0; expected a step 1..40"),
                                       ({"from_step": 41}, "--from-step 41; expected a step 1..40"),
                                       ({"from_step": 2, "restart": True}, "give one of them")])
def test_bad_starts_are_refused(plan_path, kw, words):
    with pytest.raises(BadInput, match=words.replace(".", r"\.")):
        opened(plan_path, **kw)


def test_never_a_file_that_is_not_a_position(plan_path, tmp_path):
    journal = tmp_path / "p.json.journal"
    journal.write_text('{"kind": "start", "format": "stringbot-journal", "version": 1}\n')
    with pytest.raises(BadInput, match="is a winding journal, not a by-hand position"):
        opened(plan_path, position_path=str(journal))
    with pytest.raises(BadInput, match="is the plan itself"):
        opened(plan_path, position_path=str(plan_path))
    mine = tmp_path / "notes.txt"
    mine.write_text("my notes")
    with pytest.raises(BadInput, match="not a by-hand position"):
        opened(plan_path, position_path=str(mine), restart=True)
    assert mine.read_text() == "my notes" and journal.read_text().startswith('{"kind": "start"')


@pytest.mark.parametrize("change, words", [({"done": 99}, "done 99; expected 0..40"),
                                           ({"version": 7}, "version 7"),
                                           ({"paces": ["x"]}, "paces"),
                                           ({"plan_sha256": 5}, "plan_sha256")])
def test_a_damaged_position_is_one_clear_refusal(plan_path, change, words):
    hw, _ = opened(plan_path)
    hw.save()
    path = position_path_for(plan_path)
    doc = json.loads(open(path).read())
    doc.update(change)
    open(path, "w").write(json.dumps(doc))
    with pytest.raises(BadInput, match="is damaged") as info:
        opened(plan_path)
    assert words in str(info.value)


def test_a_colour_plan_says_which_thread_to_cut_and_which_to_tie_on(tmp_path):
    plan = colour_plan(pins=300, n=(5, 4, 3))
    hw = HandWinding(plan, plan_path="c.json", position_path=str(tmp_path / "c.json.by-hand"), size_mm=500.0)
    a, b = plan.layer_starts[1], plan.layer_starts[2]
    firsts = [s for s in hw.steps if s.tie_on]
    assert [s.index for s in firsts] == [0, a, b]
    assert firsts[0].tie_on.startswith("tie the blue (#1f5bb5) thread on at pin")
    assert firsts[1].tie_on == (f"cut the blue (#1f5bb5) thread and tie it off at pin {plan.sequence[a - 1]}; "
                                f"tie the red (#c8102e) thread on at pin {plan.sequence[a]} (thread 2 of 3)")
    assert [s.thread_left for s in hw.steps[a:b]] == [4, 3, 2, 1]
    assert hw.steps[a - 1].next_pin is None                 # a thread's last pin: the next is another thread
    said = hw.utterance(firsts[1])
    assert said.startswith("Change thread: cut the blue thread") and "#" not in said
    hw.go(a + 2, now=0.0)
    p = hw.progress()
    assert (p.layer, p.layers, p.thread_left) == (1, 3, 3)
    assert p.thread_left_m == pytest.approx(thread_metres(plan, 500.0, plan.layers[1].sequence[0:]))


def test_what_is_said(plan_path):
    hw, _ = opened(plan_path)
    s = hw.steps[1]
    words = {"cw": "clockwise", "ccw": "counter-clockwise"}
    assert hw.utterance(s) == f"pin {s.pin}" + (f", {words[s.wrap]}." if s.wrap in words else ".")
    assert hw.utterance(hw.steps[0]).startswith(f"Tie the thread on at pin {hw.steps[0].pin}")
    hw.go(40, now=0.0)
    hw.next(now=1.0)
    assert hw.utterance() == f"Done. All 40 steps. Tie the thread off at pin {hw.plan.sequence[-1]}."


def test_one_thread_that_is_not_black_on_white_is_named(tmp_path):
    plan = colour_plan(pins=120, layers=[("#f4f4f0", [3, 50, 7, 90])])
    plan.background = "#000000"
    hw = HandWinding(plan, plan_path="w.json", position_path=str(tmp_path / "w.json.by-hand"))
    assert hw.steps[0].tie_on == "tie the white (#f4f4f0) thread on at pin 3"
    assert hw.utterance(hw.steps[0]).startswith("Tie the white thread on at pin 3")
