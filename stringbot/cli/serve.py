"""``stringbot serve``: the workshop page, in a browser."""

import click

from . import cli


@cli.command("serve")
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address to listen on: 127.0.0.1 is this computer only; 0.0.0.0 lets the workshop's other "
                   "computers in (anyone on the network can then wind: the page has no password).")
@click.option("--port", type=click.IntRange(0, 65535), default=8000, show_default=True,
              help="TCP port of the page (0: any free one, printed).")
@click.option("--plans", "plans", default="stringbot-plans", show_default=True, type=click.Path(),
              help="Folder of the plans, their previews and journals, the uploaded pictures and the simulators "
                   "(made when it is not there).")
def serve_cmd(host, port, plans):
    """Serve the workshop page: plan, wind, watch and resume in a browser (Ctrl-C stops the server;
    each running winding is stopped the Ctrl-C way first, journaled and resumable)."""
    from ..workshop import plans_folder, serve

    folder = plans_folder(plans)

    def ready(url):
        click.echo(f"workshop: {url} (plans folder {folder}); Ctrl-C to stop", err=True)

    serve(folder, host=host, port=port, ready=ready)
    click.echo("workshop: stopped", err=True)
