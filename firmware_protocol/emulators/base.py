"""The interface every simulated firmware offers its transports (``sim://`` and the pty).

An emulator is a pure state machine over bytes and a virtual clock: the
transport hands it the bytes the host wrote (:meth:`Emulator.receive`), takes
the bytes the firmware has ready (:meth:`Emulator.transmit`) and decides how
time passes (:meth:`Emulator.advance`): as fast as possible (jump to the next
event) or at real speed (advance by the wall-clock time that elapsed).  It does
no I/O of its own and starts no threads.

``port_up`` is False while a fault has dropped the port (a pulled USB cable, a
power loss): the transport then closes the port and reopens it once the
emulator reports it up again (advance time to get there).
"""

__all__ = ["Emulator"]


class Emulator:
    """Base class and contract of a simulated firmware.

    Attributes
    ----------
    now : float
        Virtual clock, seconds since the emulator was created.
    port_up : bool
        False while a fault has dropped the port.
    """

    def __init__(self):
        self.now = 0.0
        self.port_up = True

    def receive(self, data: bytes) -> None:
        """Bytes from the host, as they arrive on the wire."""
        raise NotImplementedError

    def transmit(self) -> bytes:
        """Bytes for the host that are ready now (drains them)."""
        raise NotImplementedError

    def advance(self, dt: float | None = None) -> float:
        """Run virtual time forward by ``dt`` seconds, or (``None``) to the next event.

        The next event is the next motion block finished, the next response
        due, or the port coming back up.  Returns the seconds advanced
        (0.0 when ``dt`` is None and nothing is pending).
        """
        raise NotImplementedError

    @property
    def busy(self) -> bool:
        """Motion or responses pending (advancing time would change something)."""
        raise NotImplementedError

    def next_event_in(self) -> float | None:
        """Seconds of virtual time until the next event, or None if nothing is pending.

        Realtime transports use it to sleep no longer than needed.  The
        default says "unknown": transports then poll.
        """
        return None

    def port_opened(self) -> bool:
        """A host opened the port.  A board that restarts then (``controller.reset_on_open``)
        does so and returns True; by default nothing happens."""
        return False

    def idle(self) -> None:
        """The transport is about to wait for the host: if the machine is at rest, the world
        writes its record now if part of it is still unwritten (see ``World.flush``)."""
        world = getattr(self, "world", None)
        if world is not None and not self.busy:
            world.flush()

    def close(self) -> None:
        """The transport is done with the emulator (flush records); optional."""
        world = getattr(self, "world", None)
        if world is not None:
            world.close()
