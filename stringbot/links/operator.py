"""What the operator does by hand at a spool change, told to a simulated machine.

On a real machine (a serial port, a socket, a pty) the operator ties the new
thread on and nothing is sent.  A ``sim://`` machine lives in this process;
its world cannot see hands, so a dry run's operator (who does what the host
asks, when it asks) is simulated here: the world is told the thread's colour
(:func:`firmware_protocol.urlhandler.protocol_sim.tie_on`), and its record
then shows which thread went round every pin.
"""

__all__ = ["tie_on"]


def tie_on(url, color, pin=None):
    """The operator tied a thread of ``color`` on at ``pin``: tell a ``sim://`` machine's world (else nothing)."""
    if not str(url).startswith("sim://"):
        return False
    from firmware_protocol.urlhandler import protocol_sim

    protocol_sim.tie_on(str(url), color, pin)
    return True
