"""``stringbot by-hand PLAN``: winding by hand in a terminal, step by step, resumed where the maker stopped.

The stepping (the position, its saved copy, the pace, what to say) is
:mod:`stringbot.winding.by_hand`; here are the screen lines, the keys
(:mod:`.hand_keys`) and the voice (:mod:`.speech`).
"""

import signal
import sys
import time

import click

from ..errors import BadInput, Interrupted
from . import cli
from .maker import frame_size_options
from .hand_keys import LEGEND, LINE_COMMANDS, Cbreak, Command, line_commands, stdin_is_terminal, terminal_commands


def _clock(seconds):
    s = int(round(seconds))
    h, m = divmod(s // 60, 60)
    return f"{h}:{m:02d}:{s % 60:02d}" if h else f"{m}:{s % 60:02d}"


class Screen:
    """The lines the maker reads (standard output) and hears (``speaker``, or None: silent)."""

    def __init__(self, hw, *, speaker=None, tty=False):
        self.hw = hw
        self.speaker = speaker
        self.tty = tty
        self._layer = None          # the thread of the step shown last (None: none shown yet)

    def echo(self, text="", *, end=True):
        click.echo(text, nl=end)

    def note(self, text):
        click.echo(text)

    def say(self, text):
        if self.speaker is not None:
            self.speaker.say(text)

    def step(self, *, prefix=""):
        """Show (and say) the current step: the thread to tie on first where one starts."""
        hw = self.hw
        s, p = hw.current, hw.progress()
        if s.tie_on:
            self.echo(f">> {s.tie_on}")
        elif s.layer != self._layer and p.layers > 1:
            self.echo(f">> on thread {s.layer + 1} of {p.layers}: {s.color_name}")
        self._layer = s.layer
        pin = click.style(str(s.pin), bold=True) if self.tty else str(s.pin)
        parts = [f"{prefix}step {s.number} of {p.total} ({p.percent:.1f} %): pin {pin}, wrap {s.wrap}"]
        parts.append(f"then pin {s.next_pin}" if s.next_pin is not None
                     else "last of this thread" if p.layers > 1 and s.index + 1 < p.total else "the last pin")
        if p.layers > 1:
            metres = f", {p.thread_left_m:.1f} m" if p.thread_left_m is not None else ""
            parts.append(f"{s.color_name.split(' (')[0]}: {p.thread_left} step(s){metres} to go on this thread")
        elif p.thread_left_m is not None:
            parts.append(f"{p.thread_left_m:.1f} m of thread to go")
        if p.eta_s is not None:
            parts.append(f"ETA {_clock(p.eta_s)} ({p.pace_s:.1f} s a step)")
        self.echo("; ".join(parts))
        self.say(("Back. " if prefix else "") + hw.utterance())


def _session(hw, commands, screen, *, clock=time.monotonic):
    """Step through ``commands`` (``(Command, arg)``) until the last step is done or the maker quits.

    Returns
    -------
    {"finished", "quit"}
    """
    screen.step()
    hw.shown(clock())
    for cmd, arg in commands:
        if cmd is Command.NEXT:
            hw.next(clock())
            if hw.current is None:
                screen.say(hw.utterance())
                return "finished"
            screen.step()
        elif cmd is Command.BACK:
            if hw.back(clock()):
                screen.step(prefix="back: ")
            else:
                screen.note("this is the first step; there is none before it")
        elif cmd is Command.REPEAT:
            screen.step()
        elif cmd is Command.GO:
            try:
                hw.go(arg, clock())
            except BadInput as exc:
                screen.note(f"go: {exc}")
                continue
            screen.step()
        elif cmd is Command.KEYS:
            screen.note(LEGEND if screen.tty else f"commands, one a line: {LINE_COMMANDS}")
        elif cmd is Command.QUIT:
            return "quit"
    return "quit"


def _resume_command(plan, position, default):
    return f"stringbot by-hand {plan}" + ("" if position == default else f" --position {position}")


def _hangup(signum, frame):
    raise KeyboardInterrupt


def _one_session(plan, position):
    """Hold a lock on the plan file while a session winds it: a second ``by-hand`` of the same plan
    at the same time would overwrite the first's position.  Returns the open file (close it to let go)."""
    import fcntl

    f = open(plan, "rb")
    try:
        fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        f.close()
        raise BadInput(f"another `stringbot by-hand` is winding {plan} now (its position: {position}); "
                       "quit that one first (q), then run this again") from None
    return f


@cli.command("by-hand", epilog="""\b
Examples:
  stringbot by-hand camera.json                      (keys: Space next, b back, r repeat, q quit)
  stringbot by-hand camera.json --speak              (each pin read aloud by espeak-ng)
  stringbot by-hand cat.json --from-step 120         (a colour plan: says when to change thread)
  printf 'next\\nnext\\nback\\nquit\\n' | stringbot by-hand camera.json   (one command a line)
""")
@click.argument("plan", type=click.Path(dir_okay=True, path_type=str))
@click.option("--restart", is_flag=True, help="Start at step 1, whatever the saved position says.")
@click.option("--from-step", "from_step", type=int, default=None,
              help="Start at step N (from 1, as `stringbot pins` counts them).")
@click.option("--position", "position", default=None, type=click.Path(dir_okay=False, path_type=str),
              help="The file that keeps the position [default: PLAN.by-hand, beside the plan].")
@click.option("--speak", is_flag=True, help="Say each pin aloud with espeak-ng (where it is installed).")
@click.option("--voice", default=None, help="--speak: the espeak-ng voice, e.g. en-us, de (espeak-ng --voices).")
@click.option("--speed", type=int, default=None, help="--speak: words a minute, 80..450 [default: espeak-ng's 175].")
@frame_size_options("the metres of thread to go [default: the plan's]")
def by_hand_cmd(plan, restart, from_step, position, speak, voice, speed, diameter_mm, machine, force):
    """Wind PLAN by hand, step by step: the pin to go to, its wrap direction, progress and ETA.

    At a terminal single keys step (Space, Enter or n: next; b or Backspace: back; r: repeat; g: go to
    a step; q: quit); from a pipe or a file, one command a line (next or an empty line, back, repeat,
    go N, quit). The position is saved after every step (PLAN.by-hand) and the next run resumes there.
    A colour plan says at the first step of each thread which thread to cut and which to tie on.
    """
    from ..planner.plan_file import read_plan
    from ..winding.by_hand import HandWinding, position_path_for
    from .maker import _frame_size
    from .speech import Speaker

    if (voice is not None or speed is not None) and not speak:
        raise BadInput("--voice and --speed are for --speak; give --speak too")
    p = read_plan(plan)
    size, _from, _mach = _frame_size(p, diameter_mm, machine, plan_path=plan, force=force)
    default = position_path_for(plan)
    position = position or default
    hw, how = HandWinding.open(p, plan_path=plan, position_path=position, size_mm=size, restart=restart,
                               from_step=from_step)
    resume = _resume_command(plan, position, default)
    if how == "resumed" and hw.current is None:
        click.echo(f"all {hw.total} steps of {plan} are done (position in {position}); --restart winds it "
                   "again, --from-step N goes back to step N")
        return
    speaker = None
    if speak:
        speaker, why = Speaker.find(voice=voice, speed=speed)
        if why:
            click.echo(why, err=True)
    tty = stdin_is_terminal()
    start = {"new": "from step 1", "restarted": "from step 1 (restarted)", "from step": f"from step {hw.done + 1}",
             "resumed": f"resumed at step {hw.done + 1} ({hw.done} done)"}[how]
    click.echo(f"by hand: {plan}, {hw.total} steps, {start}; pins {hw.header['pins']}; the position is kept in "
               f"{position}")
    click.echo(f"wrap: {hw.header['wrap']}")
    click.echo(LEGEND if tty else f"commands, one a line: {LINE_COMMANDS}")
    lock = _one_session(plan, position)
    hw.save()                     # where this session starts, before the first key
    screen = Screen(hw, speaker=speaker, tty=tty and sys.stdout.isatty())
    old = {s: signal.signal(s, _hangup) for s in (signal.SIGTERM, getattr(signal, "SIGHUP", signal.SIGTERM))}
    try:
        if tty:
            fd = sys.stdin.fileno()
            with Cbreak(fd):
                commands = terminal_commands(fd, screen.echo, hw.total,
                                             unknown=lambda key: screen.note(f"key {key!r} does nothing; ? shows the keys"))
                outcome = _session(hw, commands, screen)
        else:
            commands = line_commands(sys.stdin, unknown=lambda line: click.echo(
                f"by-hand: {line!r} is no command; expected {LINE_COMMANDS}", err=True))
            outcome = _session(hw, commands, screen)
    except KeyboardInterrupt:
        raise Interrupted(f"interrupted at step {hw.done + 1} of {hw.total}; the position is saved in {position}: "
                          f"resume with: {resume}") from None
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        if speaker is not None:
            speaker.close(wait_s=0 if hw.current is not None else 3.0)
        lock.close()
    if outcome == "finished":
        last = hw.last
        click.echo(f"done: all {hw.total} steps; tie the thread off at pin {last.pin} (position in {position})")
        return
    s = hw.current
    click.echo(f"stopped at step {s.number} of {hw.total} (pin {s.pin}); the position is saved in {position}: "
               f"{resume} resumes there")
