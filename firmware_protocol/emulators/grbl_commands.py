"""GRBL's ``$`` system commands, as the simulated firmware answers them.

``$`` help, ``$$`` settings, ``$x=val``, ``$#`` parameters, ``$G`` parser state,
``$I`` build info, ``$N`` startup lines, ``$C`` check mode, ``$X`` unlock,
``$H`` homing, ``$J=`` jogging, ``$SLP`` sleep, ``$RST=`` restore.  Each returns
GRBL's status code (0 = ``ok``) or, for commands that take time, a generator
the emulator's main loop runs (see :class:`~.grbl.GrblEmulator`).
"""

from .grbl_parser import GrblError, fmt
from .grbl_system import GrblState

__all__ = ["system_command"]

HELP = "[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $SLP $C $X $H ~ ! ? ctrl-x]"


def system_command(emu, text):
    st = emu.state
    if text == "$":
        emu._emit(HELP)
        return 0
    if text.startswith("$J"):
        if not text.startswith("$J="):
            return 3
        if st not in (GrblState.IDLE, GrblState.JOG):
            return 8
        return _jog(emu, text[3:])
    if text in ("$$", "$G", "$C", "$X"):
        if text == "$$":
            if st in (GrblState.RUN, GrblState.HOLD):
                return 8
            for line in emu.format_settings():
                emu._emit(line)
        elif text == "$G":
            emu._emit(emu.parser.state.report())
        elif text == "$C":
            return _check_mode(emu)
        elif text == "$X":
            if st is GrblState.ALARM:
                emu._emit("[MSG:Caution: Unlocked]")
                emu.state = GrblState.IDLE
        return 0
    if text[1:2] in ("$", "G", "C", "X"):
        return 3
    if st not in (GrblState.IDLE, GrblState.ALARM):
        return 8
    if text == "$#":
        _parameters(emu)
        return 0
    if text.startswith("$H"):
        if text != "$H":
            return 3
        if not emu.settings[22]:
            return 5
        return emu._home()
    if text == "$SLP":
        emu._emit("[MSG:Sleeping]")
        emu.state = GrblState.SLEEP
        return 0
    if text.startswith("$I"):
        if text == "$I":
            for line in emu.variant.build_info(emu.axes, emu.user_string):
                emu._emit(line)
            return 0
        if text.startswith("$I="):
            emu.user_string = text[3:]
            return 0
        return 3
    if text.startswith("$RST="):
        if text[5:] not in ("$", "#", "*"):
            return 3
        emu.restore(text[5])
        emu._emit("[MSG:Restoring defaults]")
        emu.after_response = emu._soft_reset      # GRBL resets itself once the ok is out
        return 0
    if text.startswith("$N"):
        if text == "$N":
            for i, line in enumerate(emu.startup_lines):
                emu._emit(f"$N{i}={line}")
            return 0
        index, eq, line = text[2:].partition("=")
        if not eq or not index.isdigit() or int(index) >= len(emu.startup_lines):
            return 3
        if line:
            try:
                saved = (emu.parser.state, list(emu.parser.position))
                from copy import deepcopy
                emu.parser.state = deepcopy(saved[0])
                emu.parser.execute(line)
            except GrblError as exc:
                return exc.code
            finally:
                emu.parser.state, emu.parser.position = saved
        emu.startup_lines[int(index)] = line
        return 0
    return _setting(emu, text[1:])


def _setting(emu, text):
    key, eq, value = text.partition("=")
    try:
        k = float(key)
    except ValueError:
        return 2
    if not eq:
        return 3
    try:
        v = float(value)
    except ValueError:
        return 2
    if k != int(k) or (k > 255 and int(k) not in emu.settings):   # grblHAL numbers past 255
        return 3
    return emu.store_setting(int(k), v)


def _check_mode(emu):
    if emu.state is GrblState.CHECK:
        emu._emit("[MSG:Disabled]")

        def then_reset():
            emu.state = GrblState.IDLE
            emu._boot(wipe=False, alarm=False)
        emu.after_response = then_reset      # GRBL resets itself once the ok is out
        return 0
    if emu.state is not GrblState.IDLE:
        return 8
    emu._emit("[MSG:Enabled]")
    emu.state = GrblState.CHECK
    return 0


def _parameters(emu):
    axes = len(emu.axes)
    inches = bool(emu.settings[13])
    k, dec = (1 / 25.4, 4) if inches else (1.0, 3)

    def vals(v):
        return ",".join(fmt(x * k, dec) for x in v[:axes])
    for i, cs in enumerate(emu.parser.coord_systems):
        emu._emit(f"[G{54 + i}:{vals(cs)}]")
    emu._emit(f"[G28:{vals(emu.parser.g28)}]")
    emu._emit(f"[G30:{vals(emu.parser.g30)}]")
    emu._emit(f"[G92:{vals(emu.parser.state.g92)}]")
    emu._emit(f"[TLO:{fmt(emu.parser.state.tlo * k, dec)}]")
    emu._emit(f"[PRB:{vals([0.0] * axes)}:0]")


def _jog(emu, block):
    """``$J=G91 X10 F500``: a jog motion (IDLE or JOG only), never changing the parser's modes.

    Checked in GRBL's order (``gc_execute_line`` with its jog flag): the words
    (error:1, 2, 20, 21, 23, 25, 4), the line number (27), the F word (22),
    unused words (36), then what a jog may hold (16: only G20/G21, G90/G91,
    G53, axis words, F and N).  A jog without axis words is error:26 here
    (GRBL 1.1h would plan a move to machine zero).
    """
    try:
        gcodes, mcodes, values, axis_words = emu.parser.read_block(block)
    except GrblError as exc:
        return exc.code
    if values.get("N", 0) > 9999999:
        return 27
    if "F" not in values:
        return 22
    if gcodes.get("nonmodal") == 4:
        if "P" not in values:
            return 28
        values.pop("P")
    if set(values) - {"N", "F"}:
        return 36
    if mcodes or set(gcodes) - {"distance", "units", "nonmodal"} or gcodes.get("nonmodal") not in (None, 53):
        return 16
    if not axis_words:
        return 26
    inches = gcodes.get("units", int(emu.parser.state.units[1:])) == 20
    absolute = gcodes.get("distance", int(emu.parser.state.distance[1:])) == 90
    machine = gcodes.get("nonmodal") == 53
    scale = 25.4 if inches else 1.0
    wco = emu.parser.wco()
    target = emu.parser._target(axis_words, scale, absolute, wco, machine=machine)
    emu.parser.position = list(target)
    return emu._queue_moves([tuple(target)], rapid=False, feed=values["F"] * scale, inverse=False,
                            line_number=0, kind="jog")
