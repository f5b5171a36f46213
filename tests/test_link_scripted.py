"""A scripted in-memory port: an exact exchange table a link must use up exactly.

Each entry is ``(expected_write, reply)``:

- ``expected_write`` bytes: the link's next ``write`` must be exactly these
  bytes; ``reply`` then becomes readable.
- ``expected_write`` None: ``reply`` becomes readable when the link reads and
  has nothing left to read (the firmware answering later, e.g. after motion).

``reply`` may be an exception instance: the read that would deliver it raises
it (a pulled cable).  A write that does not match fails the test at once.
"""

from collections import deque

Step = tuple


class ScriptedPort:
    def __init__(self, table):
        self.table = deque(table)
        self.rx = bytearray()
        self.written = []
        self.closed = False
        self.timeout = 0.0

    # the pyserial surface the links use
    @property
    def in_waiting(self):
        return len(self.rx)

    def write(self, data):
        data = bytes(data)
        self.written.append(data)
        assert self.table, f"unexpected write {data!r}: the table is used up"
        expect, reply = self.table[0]
        assert expect is not None, f"unexpected write {data!r}: the firmware was due to answer {reply!r}"
        assert data == expect, f"wrote {data!r}, the table expects {expect!r}"
        self.table.popleft()
        self._deliver(reply)
        return len(data)

    def _deliver(self, reply):
        if isinstance(reply, BaseException):
            raise reply
        self.rx += reply

    def read(self, n=1):
        if not self.rx and self.table and self.table[0][0] is None:
            _, reply = self.table.popleft()
            self._deliver(reply)
        out = bytes(self.rx[:n])
        del self.rx[:n]
        return out

    def close(self):
        self.closed = True

    def assert_done(self):
        assert not self.table, f"table not used up; next: {self.table[0]!r}"


def test_the_scripted_port_fails_on_a_wrong_write_and_an_unused_table():
    import pytest
    port = ScriptedPort([(b"a\n", b"ok\r\n"), (None, b"late\r\n")])
    port.write(b"a\n")
    assert port.read(10) == b"ok\r\n"
    with pytest.raises(AssertionError):
        port.assert_done()
    assert port.read(10) == b"late\r\n"
    port.assert_done()
    with pytest.raises(AssertionError):
        port.write(b"b\n")
