"""The GRBL / grblHAL link as exact exchange tables over a scripted port."""

import pytest
import serial

from stringbot.errors import MachineFailure
from stringbot.links import GrblLink, parse_status

from test_link_scripted import ScriptedPort

BANNER = b"\r\nGrbl 1.1h ['$' for help]\r\n"
I_GRBL = b"[VER:1.1h.20190825:]\r\n[OPT:V,15,128]\r\nok\r\n"
I_HAL = b"[VER:1.1f.20230125:]\r\n[OPT:VNML+,100,1024,3,0]\r\n[FIRMWARE:grblHAL]\r\nok\r\n"


def link(table, dialect="grbl", **kw):
    port = ScriptedPort(table)
    kw.setdefault("response_timeout", 0.3)
    kw.setdefault("poll_interval", 0.05)
    return GrblLink(port, dialect, **kw), port


def test_identify_grbl_reads_banner_and_buffer():
    lk, port = link([(None, BANNER), (b"$I\n", I_GRBL)])
    info = lk.identify()
    assert info.dialect == "grbl" and info.version == "1.1h"
    assert lk.rx_size == 127
    port.assert_done()


def test_identify_grblhal_buffer_from_dollar_i():
    lk, port = link([(None, b"GrblHAL 1.1f ['$' or '$HELP' for help]\r\n"), (b"$I\n", I_HAL)],
                    "grblhal")
    info = lk.identify()
    assert info.dialect == "grblhal" and lk.rx_size == 1024
    port.assert_done()


@pytest.mark.parametrize("dialect, table, words", [
    ("grbl", [(b"$I\n", I_HAL)], "runs grblHAL"),
    ("grblhal", [(None, BANNER), (b"$I\n", I_GRBL)], "runs GRBL"),
    ("grbl", [(b"$I\n", b"echo:Unknown command: \"$I\"\r\nok\r\n")], "runs Marlin"),
    ("grbl", [(b"$I\n", b"hello world\r\n")], "not GRBL"),
    ("grbl", [(b"$I\n", b"")], "no answer"),
    ("grbl", [(b"$I\n", b"\xff\xfe\x00garbage\r\n")], "garbage"),
])
def test_wrong_or_silent_firmware_refused(dialect, table, words):
    lk, port = link(table, dialect)
    with pytest.raises(MachineFailure, match=words):
        lk.identify()
    port.assert_done()


def ready(extra, dialect="grbl", **kw):
    lk, port = link([(None, BANNER), (b"$I\n", I_GRBL)] + extra, dialect, **kw)
    lk.identify()
    return lk, port


def test_a_banner_after_the_query_is_waited_out_not_answered_twice():
    # the board printed its banner while our $I was on its way: the answer still comes, once
    lk, port = link([(b"$I\n", BANNER + I_GRBL)])
    assert lk.identify().version == "1.1h"
    port.assert_done()


def test_a_query_lost_in_a_reset_is_asked_again():
    lk, port = link([(b"$I\n", BANNER), (b"$I\n", I_GRBL)])
    assert lk.identify().version == "1.1h"
    port.assert_done()


def test_prepare_homes_when_asked_and_sets_modal_state():
    lk, port = ready([
        (b"?", b"<Alarm|MPos:0.000,0.000,0.000|FS:0,0>\r\n"),
        (b"$H\n", b"ok\r\n"),
        (b"G21\n", b"ok\r\n"),
        (b"G90\n", b"ok\r\n"),
    ])
    lk.prepare(home=True, preamble=["G21 ; mm", "G90"])
    port.assert_done()


def test_alarm_without_homing_refused():
    lk, port = ready([(b"?", b"<Alarm|MPos:0.000,0.000,0.000|FS:0,0>\r\n")])
    with pytest.raises(MachineFailure, match="alarm"):
        lk.prepare(home=False)
    port.assert_done()


class FakeStep:
    def __init__(self, index, pin, lines):
        self.index, self.pin, self.lines = index, pin, lines


def lines_for(step):
    return step.lines


def test_character_counting_fills_but_never_exceeds_the_buffer():
    # 127 usable bytes, 3 of them kept for the $G probe: lines of 20 bytes -> 6 in flight
    # (120), the 7th waits for an ok
    body = [f"G1 X{i:04d}.000 F99999" for i in range(8)]      # 19 chars + \n = 20
    assert all(len(b) == 19 for b in body)
    table = [(f"{b}\n".encode(), b"") for b in body[:6]]
    table += [(None, b"ok\r\n"), (f"{body[6]}\n".encode(), b""),
              (None, b"ok\r\n"), (f"{body[7]}\n".encode(), b""),
              (None, b"ok\r\n"), (b"G4 P0\n", b"")]    # 120 + 6 > 124: the sync waits for an ok
    table += [(None, b"ok\r\n")] * 6
    lk, port = ready(table)
    done = []
    lk.execute([FakeStep(0, 5, body)], lines_for, done.append)
    assert [s.index for s in done] == [0]
    assert lk.max_inflight_bytes <= 127
    port.assert_done()


def test_step_executed_only_after_its_sync_is_answered():
    s0 = FakeStep(0, 5, ["G0 X1"])
    s1 = FakeStep(1, 9, ["G0 X2 ; go"])
    seen = []
    table = [(b"G0 X1\n", b""), (b"G4 P0\n", b""),
             (b"G0 X2\n", b"ok\r\n"), (b"G4 P0\n", b""),
             (None, b"ok\r\n"), (None, b"ok\r\n"), (None, b"ok\r\n")]
    lk, port = ready(table)

    def on_done(step):
        seen.append((step.index, lk.unanswered_count()))
    lk.unanswered_count = lambda: len(lk.unanswered())
    lk.execute([s0, s1], lines_for, on_done)
    # step 0 only after the 2nd ok (its G4 P0), step 1 after the 4th
    assert seen == [(0, 2), (1, 0)]
    port.assert_done()


def test_error_stops_the_job_naming_pin_and_step():
    table = [(b"G0 X1\n", b""), (b"G4 P0\n", b""), (b"G0 Q1\n", b""), (b"G4 P0\n", b""),
             (None, b"ok\r\nok\r\n"), (None, b"error:20\r\n"), (b"!", b"")]
    lk, port = ready(table)
    with pytest.raises(MachineFailure) as info:
        lk.execute([FakeStep(0, 5, ["G0 X1"]), FakeStep(1, 9, ["G0 Q1"])], lines_for)
    text = str(info.value)
    assert "error:20" in text and "pin 9" in text and "step 2" in text
    port.assert_done()


def test_alarm_mid_job_names_pin_and_step():
    table = [(b"G0 X1\n", b""), (b"G4 P0\n", b""), (None, b"ALARM:2\r\n")]
    lk, port = ready(table)
    with pytest.raises(MachineFailure, match=r"ALARM:2.*pin 5, step 1"):
        lk.execute([FakeStep(0, 5, ["G0 X1"])], lines_for)
    port.assert_done()


def test_reset_banner_mid_job_is_a_failure():
    table = [(b"G0 X1\n", b""), (b"G4 P0\n", b""), (None, b"ok\r\n" + BANNER)]
    lk, port = ready(table)
    with pytest.raises(MachineFailure, match=r"reset itself.*pin 5, step 1"):
        lk.execute([FakeStep(0, 5, ["G0 X1"])], lines_for)
    port.assert_done()


def test_garbage_mid_job_is_a_failure_and_holds():
    table = [(b"G0 X1\n", b""), (b"G4 P0\n", b""), (None, b"o#k\r\n"), (b"!", b"")]
    lk, port = ready(table)
    with pytest.raises(MachineFailure, match="garbage"):
        lk.execute([FakeStep(0, 5, ["G0 X1"])], lines_for)
    port.assert_done()


IDLE = b"<Idle|MPos:1.000,0.000,0.000|Bf:15,127|FS:0,0>\r\n"
GC = b"[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]\r\n"


def test_silence_then_lost_ok_is_recovered_by_the_g_probe():
    # idle twice with the sync unanswered: $G is asked; its [GC:...] accounts for the lost ok
    table = [(b"G0 X1\n", b""), (b"G4 P0\n", b""), (None, b"ok\r\n"),    # the sync's ok is lost
             (b"?", IDLE), (b"?", IDLE), (b"$G\n", GC + b"ok\r\n"),
             (b"G4 P0\n", b"ok\r\n")]                 # finish: the probe's ok, then its own
    lk, port = ready(table)
    done = []
    lk.execute([FakeStep(0, 5, ["G0 X1"])], lines_for, done.append)
    assert len(done) == 1
    lk.finish()
    assert lk.unanswered() == []
    port.assert_done()


def test_a_lost_ok_of_the_probe_itself_is_survived():
    # streaming: the probe's ok is lost; the next ok is taken for it, and a new probe accounts
    table = [(b"G0 X1\n", b""), (b"G4 P0\n", b""), (None, b"ok\r\n"),
             (b"?", IDLE), (b"?", IDLE), (b"$G\n", GC),                  # the probe's ok is lost too
             (b"G4 P0\n", b"ok\r\n"),
             (b"?", IDLE), (b"?", IDLE), (b"$G\n", GC + b"ok\r\n")]
    lk, port = ready(table)
    done = []
    lk.execute([FakeStep(0, 5, ["G0 X1"])], lines_for, done.append)
    assert len(done) == 1
    lk.finish()
    lk._poll()                                  # the second probe's ok, already waiting
    assert lk.unanswered() == []
    port.assert_done()


def test_a_probe_whose_ok_is_lost_last_is_dropped():
    table = [(b"G0 X1\n", b""), (b"G4 P0\n", b""), (None, b"ok\r\n"),
             (b"?", IDLE), (b"?", IDLE), (b"$G\n", GC),                  # the probe's ok is lost too
             (b"?", IDLE), (b"?", IDLE)]
    lk, port = ready(table)
    lk.finish(["G0 X1"])
    assert len(lk.unanswered()) == 1                # the probe: its [GC:...] came, its ok did not
    lk._wait_answers(0, 5.0)                        # idle twice more: the probe is done
    assert lk.unanswered() == [] and lk._inflight_bytes == 0
    port.assert_done()


def test_idle_during_a_long_dwell_credits_nothing():
    # GRBL reports Idle during G4: the dwell outlasts the idle window several times over.
    # Nothing may be counted done until the answers come; the probe waits behind the dwell.
    s0 = FakeStep(0, 5, ["G1 X0010.000 F99999", "G4 P3.0"])
    s1 = FakeStep(1, 9, ["G1 X0020.000 F99999", "G4 P3.0"])
    events = []
    table = [(b"G1 X0010.000 F99999\n", b""), (b"G4 P3.0\n", b""), (b"G4 P0\n", b""),
             (b"G1 X0020.000 F99999\n", b""), (b"G4 P3.0\n", b""), (b"G4 P0\n", b""),
             (None, b"ok\r\n"),                                  # the move is queued; dwell starts
             (b"?", IDLE), (b"?", IDLE),
             (b"$G\n", b""),                                      # behind the dwell: no answer yet
             (b"?", IDLE), (b"?", IDLE),                           # still dwelling: no second probe
             (b"?", IDLE), (b"?", IDLE),
             (None, b"ok\r\nok\r\n"),                            # dwell, then sync of step 1
             (None, b"ok\r\n"),                                  # step 2's move
             (b"?", IDLE), (b"?", IDLE),                           # step 2's dwell
             (None, b"ok\r\nok\r\n" + GC + b"ok\r\n")]
    lk, port = ready(table)
    lk.execute([s0, s1], lines_for, lambda st: events.append((st.index, len(lk.unanswered()))))
    # step 1 only when its sync was answered (then 4 lines were left: step 2's 3 and the
    # probe), step 2 when its own sync was (the probe's ok may still be unread)
    assert events[0] == (0, 4) and events[1][0] == 1
    lk._poll()
    assert lk.unanswered() == []
    assert lk.max_inflight_bytes <= lk.rx_size
    port.assert_done()


def test_dwell_with_idle_replies_never_oversends_the_buffer():
    # steps with a dwell longer than the idle window, enough to fill the buffer: every line
    # waits for a real answer, and the count (probe included) never passes the buffer
    steps = [FakeStep(i, i, [f"G1 X{i:04d}.000 F99999", "G4 P2.5"]) for i in range(4)]
    a = [f"G1 X{i:04d}.000 F99999\n".encode() for i in range(4)]
    d, s = b"G4 P2.5\n", b"G4 P0\n"
    assert len(a[0]) + len(d) + len(s) == 34 and lk_room(127) == 124
    table = [(x, b"") for i in range(3) for x in (a[i], d, s)] + [(a[3], b"")]   # 122 bytes
    table += [(None, b"ok\r\n"),                               # step 1's move: 102 bytes
              (d, b""), (s, b""),                              # 110, then 116: both fit
              (b"?", IDLE), (b"?", IDLE),                      # step 1's dwell runs
              (b"$G\n", b""),                                  # 119: the probe waits behind it
              (b"?", IDLE), (b"?", IDLE)]                      # still dwelling: nothing credited
    for i in range(3):                                         # dwell + sync, next move + dwell
        table += [(None, b"ok\r\nok\r\n"), (None, b"ok\r\n"), (b"?", IDLE), (b"?", IDLE)]
    table += [(None, b"ok\r\nok\r\n" + GC + b"ok\r\n")]
    lk, port = ready(table, lookahead=3)
    events = []
    lk.execute(steps, lines_for, lambda st: events.append((st.index, len(lk.unanswered()))))
    # each step only once its own sync is answered: 10, 7, 4 lines (the probe included) left
    assert events[:3] == [(0, 10), (1, 7), (2, 4)] and events[3][0] == 3
    lk._poll()
    assert lk.unanswered() == []
    assert lk.max_inflight_bytes == 122
    port.assert_done()


def lk_room(rx):
    return rx - len(b"$G\n")


def test_silent_machine_times_out_with_a_clear_line():
    table = [(b"G0 X1\n", b""), (b"G4 P0\n", b""), (b"?", b"")]
    lk, port = ready(table)
    with pytest.raises(MachineFailure, match=r"stopped answering.*pin 5, step 1"):
        lk.execute([FakeStep(0, 5, ["G0 X1"])], lines_for)
    port.assert_done()


def test_disconnect_mid_job_is_a_failure():
    table = [(b"G0 X1\n", b""), (b"G4 P0\n", b""), (None, serial.SerialException("device disconnected"))]
    lk, port = ready(table)
    with pytest.raises(MachineFailure, match=r"lost the connection.*pin 5, step 1"):
        lk.execute([FakeStep(0, 5, ["G0 X1"])], lines_for)
    port.assert_done()


def test_feed_hold_waits_for_the_machine_to_stop():
    table = [(b"!", b""), (b"?", b"<Hold:1|MPos:1.000,0.000,0.000|FS:0,0>\r\n"),
             (b"?", b"<Hold:0|MPos:1.500,0.000,0.000|FS:0,0>\r\n")]
    lk, port = ready(table)
    st = lk.hold()
    assert st.state == "Hold" and st.sub == "0" and st.mpos == (1.5, 0.0, 0.0)
    port.assert_done()


def test_parse_status_forms():
    st = parse_status("<Idle|MPos:1.000,2.000,3.000|Bf:15,128|FS:0,0>")
    assert st.state == "Idle" and st.mpos == (1.0, 2.0, 3.0) and st.fields["Bf"] == "15,128"
    st = parse_status("<Hold:0|WPos:1.0,2.0,3.0,4.0>")
    assert st.stopped and st.mpos == (1.0, 2.0, 3.0, 4.0)
    assert not parse_status("<Run|MPos:0,0,0>").stopped


def test_error_and_alarm_words_come_from_the_device_tables():
    from firmware_protocol import grbl as codes
    from stringbot.links.grbl import _alarm_words, _error_words

    # error 11 and alarm 3 have words in GRBL's tables (the host once fell back to a partial copy)
    assert _error_words(11) == f"error:11 ({codes.ERROR_CODES[11]})"
    assert _alarm_words(3) == f"ALARM:3 ({codes.ALARM_CODES[3]})"
    assert "unknown" in _error_words(999)
