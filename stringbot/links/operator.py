"""What the operator does by hand at a spool change, told to a simulated machine.

On a real machine (a serial port, a socket) the operator ties the new thread
on and nothing is sent.  A simulator served on a pty (``stringbot simulate``)
listens beside it for what the operator did
(:func:`firmware_protocol.pty.tell_operator`): it is told the colour too.  A ``sim://`` machine lives in this process;
its world cannot see hands, so a dry run's operator (who does what the host
asks, when it asks) is simulated here: the world is told the thread's colour
(:func:`firmware_protocol.urlhandler.protocol_sim.tie_on`), and its record
then shows which thread went round every pin.
"""

__all__ = ["tie_on"]


def tie_on(url, color, pin=None):
    """The operator tied a thread of ``color`` on at ``pin``: tell a simulated machine's world
    (``sim://``, or a simulator on a pty); True when one was told."""
    if not str(url).startswith("sim://"):
        if "://" in str(url):
            return False
        from firmware_protocol.pty import tell_operator
        return tell_operator(str(url), {"tie_on": color, "pin": None if pin is None else int(pin)})
    from firmware_protocol.urlhandler import protocol_sim

    protocol_sim.tie_on(str(url), color, pin)
    return True
