"""Who answers on a GRBL-family port, and its settings: the identification half of :class:`GrblLink`.

The firmware is told apart by the family's one detector (:func:`firmware_protocol.grbl.identify`,
reading the records of :mod:`firmware_protocol.kinds`): its banner on connect and its answer to
``$I``.  A firmware that is not the machine file's kind is refused, naming both.
"""

import logging
import re
import time

from firmware_protocol import grbl as grbl_codes

from .base import FirmwareInfo, LinkState

__all__ = ["GrblIdentify"]

log = logging.getLogger(__name__)

_SETTING = re.compile(r"^\$(\d+)=(-?\d+(?:\.\d*)?)")


class GrblIdentify:
    """Identification and ``$$`` for :class:`~stringbot.links.grbl.GrblLink` (a mixin: it uses the
    link's port I/O, ``kind``, ``dialect`` and ``status``)."""

    # ---- identification --------------------------------------------------------------
    def identify(self):
        """Find out who answers; refuse anything that is not the machine's dialect.

        Reads the banner if the firmware prints one on connect, then asks ``$I``.
        """
        seen = self.drain_input(quiet=0.05, limit=2.5)
        answer = self._ask("$I", seen)
        lines = tuple(seen) + tuple(answer)
        joined = " ".join(lines)
        if "Marlin" in joined or "FIRMWARE_NAME" in joined or "Unknown command" in joined:
            raise self.fail(f"the machine runs Marlin, but machine file says {self.dialect!r}; "
                            "use a machine file for Marlin or check the port")
        found = grbl_codes.identify(lines)
        if found is None:
            busy = self._busy_state(lines)
            if busy:
                raise self.fail(busy)
            if lines:
                raise self.fail(f"the device on the port is not {self.kind.title} (nor another of GRBL's "
                                f"family); it answered {lines[0][:60]!r}")
            raise self.fail(f"no answer from the machine (expected {self.kind.title}'s banner or $I); "
                            "check the port, the baud rate and that the machine is on")
        if found.kind != self.dialect:
            raise self.fail(f"the machine runs {found.title} {found.version}, but the machine file says "
                            f"dialect {self.dialect!r}")
        if found.rx_buffer:   # the reported size, less what the firmware's ring buffer keeps free
            self.rx_size = found.rx_buffer - self.kind.rx_reserve
        if found.planner_blocks:
            self.planner_blocks = found.planner_blocks
        self.info = FirmwareInfo(dialect=found.kind, name=found.title, version=found.version,
                                 rx_buffer=self.rx_size, lines=lines)
        self.state = LinkState.IDENTIFIED
        log.info("firmware: %s %s, receive buffer %d bytes", self.info.name, found.version, self.rx_size)
        return self.info

    def restarted(self, line):
        """The start-up line of any firmware of GRBL's family (one detector: firmware_protocol.grbl)."""
        return grbl_codes.is_banner(line)

    def _busy_state(self, lines):
        """A GRBL that refuses ``$I`` (``error:8``, not idle) because it holds or runs: say so."""
        if not any(x.startswith("error") for x in lines):
            return None
        try:
            self.write(b"?")
            for _ in range(5):
                line = self.readline(self.response_timeout)
                if line is None:
                    return None
                if line.startswith("<"):
                    st = self._status(line)
                    break
            else:
                return None
        except Exception:
            return None
        if st.state == "Hold":
            return ("the machine is GRBL in Hold (a feed hold is waiting, so it answers nothing else): "
                    "send ~ to let it go on, or reset it (Ctrl-X), then run again")
        if st.state in ("Run", "Jog", "Home"):
            return (f"the machine is GRBL, busy ({st.state}): another program may be running a job on it; "
                    "wait for it or stop it, then run again")
        if st.state == "Door":
            return "the machine is GRBL with its safety door open: close it, then run again"
        return None

    def _ask(self, text, seen):
        """Send a query in send-response fashion.

        A banner arriving meanwhile means the board (re)started: the query may
        have been lost in the reset (a real Arduino resets when its port opens),
        so it is sent once more if no answer follows soon after the banner.
        """
        self.write(text.encode("ascii") + b"\n")
        lines = []
        deadline = time.monotonic() + self.response_timeout
        resent = banner = False
        while True:
            line = self.readline(max(0.0, deadline - time.monotonic()))
            if line is None:
                if banner and not resent:
                    resent = True
                    self.write(text.encode("ascii") + b"\n")
                    deadline = time.monotonic() + self.response_timeout
                    continue
                return lines
            if line.startswith("ok") or line.startswith("error"):
                lines.append(line)
                return lines
            if self.restarted(line):
                seen.append(line)
                lines = []
                banner = True
                deadline = min(deadline, time.monotonic() + 0.5)
                continue
            lines.append(line)

    def read_settings(self):
        """``$$``: the firmware's settings as ``{number: value}`` (e.g. ``{100: 44.444, ...}``).

        Sent between jobs (nothing in flight).  A firmware that answers none gives ``{}``.
        """
        settings = {}
        for line in self._ask("$$", []):
            m = _SETTING.match(line)
            if m:
                settings[int(m.group(1))] = float(m.group(2))
        self.settings = settings
        return settings
