"""Exchange tables: check an emulator (or any byte-level device) against expected bytes.

A table is a list of ``(sent, expected)`` byte pairs, in the style of
pymeasure's protocol tests.  For each pair the bytes are delivered, then the
device's output is collected -- running its virtual clock to the next event
while fewer bytes than expected have come and something is still pending --
and must equal ``expected`` exactly.  Nothing may be left over at the end.
``sent`` may be ``b""`` to just wait for output; ``expected`` may be ``b""``
to check that nothing comes back yet.
"""

__all__ = ["ExchangeMismatch", "run_exchange", "collect"]


class ExchangeMismatch(AssertionError):
    """The device answered something else than the table says."""


def collect(emulator, size, max_events=100000):
    """Bytes from ``emulator`` until ``size`` have come or nothing is pending."""
    out = bytearray(emulator.transmit())
    events = 0
    while len(out) < size and emulator.busy and events < max_events:
        emulator.advance(None)
        out += emulator.transmit()
        events += 1
    return bytes(out)


def run_exchange(emulator, table):
    """Play ``table`` against ``emulator``; raises ExchangeMismatch naming the step on a difference."""
    for step, (sent, expected) in enumerate(table):
        if sent:
            emulator.receive(sent)
        got = collect(emulator, len(expected))
        if got != expected:
            raise ExchangeMismatch(f"step {step}: sent {sent!r}: expected {expected!r}, got {got!r}")
    left = emulator.transmit()
    if left:
        raise ExchangeMismatch(f"left over after the table: {left!r}")
