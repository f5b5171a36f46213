"""The workshop page (``stringbot serve``): plan, wind, watch and resume from a browser.

One local process serves a page (static HTML and JavaScript, no build step) over a plans
folder.  Every action of the page is a ``stringbot`` command run in that folder
(:mod:`.commands`): ``plan``, ``machines check``, ``wind`` (its operator asked through
``--questions json``), ``simulate --pty``; so the page does what the command line does, on
the same library calls, and shows each command.  A winding runs in its own process
(:mod:`.winding`): closing the browser never stops it, every browser sees the same state
(pushed by server-sent events), and the journal is the truth, so a crash of the server loses
nothing.  Nothing here prints: the command line (``stringbot.cli.serve``) does.
"""

import asyncio
import errno
import logging
import signal
from pathlib import Path

from ..errors import BadInput

__all__ = ["serve", "plans_folder"]

log = logging.getLogger(__name__)


def plans_folder(path):
    """The plans folder at ``path``, made when it is not there; BadInput when it cannot be."""
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise BadInput(f"--plans {str(p)!r} is a file; expected a folder (made when it is not there)")
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BadInput(f"--plans {str(p)!r} cannot be made: {exc.strerror or exc}; expected a folder you can "
                       "write") from None
    return p.resolve()


def serve(folder, *, host="127.0.0.1", port=8000, ready=None):
    """Serve the workshop over ``folder`` on ``host``:``port`` until Ctrl-C (or SIGTERM).

    ``ready(url)`` is called once it listens.  At the end each running winding is stopped the
    Ctrl-C way (feed hold, journaled: resumable) and the workshop's simulators end.

    Raises
    ------
    BadInput
        The address cannot be listened on (in use, not this machine's, an unknown host).
    """
    asyncio.run(_serve(folder, host, port, ready))


async def _serve(folder, host, port, ready):
    from aiohttp import web

    from .server import make_app

    runner = web.AppRunner(make_app(folder), handle_signals=False, access_log=None)
    await runner.setup()
    site = web.TCPSite(runner, host, port)
    try:
        await site.start()
    except OSError as exc:
        await runner.cleanup()
        raise BadInput(_listen_error(host, port, exc)) from None
    bound = runner.addresses[0]
    shown = f"[{bound[0]}]" if ":" in str(bound[0]) else bound[0]
    main = asyncio.current_task()
    loop = asyncio.get_running_loop()
    # Ctrl-C and SIGTERM end the server (even where a shell started it with SIGINT ignored, in the
    # background: its children, the windings, then get the default and so their Ctrl-C path)
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, main.cancel)
    try:
        if ready is not None:
            ready(f"http://{shown}:{bound[1]}/")
        await asyncio.Event().wait()
    except asyncio.CancelledError:
        pass
    finally:
        for sig in (signal.SIGINT, signal.SIGTERM):     # the windings are being stopped: let that finish
            loop.add_signal_handler(sig, log.warning, "stopping the windings and simulators first; a moment")
        await runner.cleanup()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.remove_signal_handler(sig)


def _listen_error(host, port, exc):
    if exc.errno == errno.EADDRINUSE:
        return (f"--port {port}: the address {host}:{port} is in use (another server listens there); expected a "
                "free port, e.g. --port 8001")
    if exc.errno in (errno.EADDRNOTAVAIL, errno.EAFNOSUPPORT):
        return f"--host {host!r} is not an address of this machine; expected e.g. 127.0.0.1 (this machine only)"
    if exc.errno == errno.EACCES:
        return f"--port {port}: permission denied (ports below 1024 need root); expected a port above 1023"
    if getattr(exc, "strerror", None) and "name" in str(exc.strerror).lower() or exc.errno in (-2, -3, -5):
        return f"--host {host!r} is not a known host name; expected an address such as 127.0.0.1 or 0.0.0.0"
    return f"cannot listen on {host}:{port}: {exc.strerror or exc}"
