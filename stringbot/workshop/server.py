"""The workshop's web server (aiohttp): the page, its JSON API and the live state by server-sent events.

Routes::

    GET  /                          the page (static HTML and JavaScript, no build step)
    GET  /api/state                 every winding, simulator and the plans' version, as JSON
    GET  /api/events                the same, pushed (text/event-stream) whenever it changes
    GET  /api/machines              the bundled machines
    GET  /api/plans                 the plans folder's plans (figures, estimates, journals)
    POST /api/plans                 plan a picture (multipart: picture + the plan form)
    GET  /api/plans/NAME            one plan;  GET /api/plans/NAME/drawing: pins and layers
    GET  /plans/NAME/preview.png    its preview as woven
    POST /api/command               the command line of a form, as the page would run it
    POST /api/check                 the settings check
    POST /api/wind                  start or resume a winding
    POST /api/windings/MACHINE/answer   answer its question;  .../stop: Ctrl-C (feed hold)

Bad input is HTTP 400 with ``{"error": "one line"}`` (the command line's own line), a busy
machine or a question answered already 409.
"""

import asyncio
import json
import logging
from importlib import resources

from aiohttp import web

from ..errors import BadInput
from .commands import Target, check_command, parse_target, plan_command, wind_command
from .workshop import Conflict, Workshop

__all__ = ["make_app", "PUSH_EVERY_S"]

log = logging.getLogger(__name__)

#: How often the live state is looked at for changes to push.
PUSH_EVERY_S = 0.25
#: While a winding runs, the state is pushed at least this often (a page sees it live).
LIVE_EVERY_S = 0.7
#: A comment line this often keeps an idle event stream open through proxies.
KEEPALIVE_S = 15.0
WORKSHOP = web.AppKey("workshop", Workshop)
HUB = web.AppKey("hub", object)


def _static(name):
    return resources.files("stringbot.workshop").joinpath("static", name).read_bytes()


def _error(exc, status):
    return web.json_response({"error": str(exc)}, status=status)


@web.middleware
async def _errors(request, handler):
    try:
        return await handler(request)
    except BadInput as exc:
        return _error(exc, 400)
    except Conflict as exc:
        return _error(exc, 409)
    except json.JSONDecodeError:
        return _error("the request's body is not JSON; expected a JSON object", 400)


class _Hub:
    """The live state, looked at every :data:`PUSH_EVERY_S` and handed to every event stream when it
    changed (each stream waits on the same condition: one snapshot for all of them)."""

    def __init__(self, workshop):
        self.workshop = workshop
        self.text = json.dumps(workshop.snapshot())
        self.version = 0
        self.changed = asyncio.Condition()
        self.open = True                # until the server's end: then every stream finishes
        self._task = None

    def start(self):
        self._task = asyncio.get_running_loop().create_task(self._watch())

    async def _watch(self):
        loop = asyncio.get_running_loop()
        pushed = loop.time()
        while True:
            await asyncio.sleep(PUSH_EVERY_S)
            try:
                text = json.dumps(self.workshop.snapshot())
            except Exception:               # never let the page's view stop the server
                log.exception("the workshop's snapshot")
                continue
            live = any(w.active for w in self.workshop.windings.values())
            if text != self.text or (live and loop.time() - pushed >= LIVE_EVERY_S):
                self.text, pushed = text, loop.time()
                self.version += 1
                async with self.changed:
                    self.changed.notify_all()

    async def stop(self):
        if self._task is not None:
            self._task.cancel()
        self.open = False
        async with self.changed:
            self.changed.notify_all()


async def index(request):
    return web.Response(body=_static("index.html"), content_type="text/html", charset="utf-8",
                        headers={"Cache-Control": "no-cache"})


async def static(request):
    name = request.match_info["name"]
    types = {".js": "text/javascript", ".css": "text/css", ".svg": "image/svg+xml"}
    kind = next((t for ext, t in types.items() if name.endswith(ext)), None)
    if kind is None or "/" in name:
        raise web.HTTPNotFound()
    try:
        body = _static(name)
    except (FileNotFoundError, OSError):
        raise web.HTTPNotFound() from None
    return web.Response(body=body, content_type=kind, charset="utf-8", headers={"Cache-Control": "no-cache"})


async def state(request):
    """The state now (the event stream's may be up to :data:`PUSH_EVERY_S` older)."""
    return web.json_response(request.app[WORKSHOP].snapshot())


async def events(request):
    """Server-sent events: the state now, then each time it changes."""
    hub = request.app[HUB]
    resp = web.StreamResponse(headers={"Content-Type": "text/event-stream", "Cache-Control": "no-cache",
                                       "X-Accel-Buffering": "no"})
    await resp.prepare(request)
    seen = -1
    try:
        while hub.open:
            if hub.version != seen:
                seen = hub.version
                await resp.write(f"id: {seen}\ndata: {hub.text}\n\n".encode())
            async with hub.changed:
                try:
                    await asyncio.wait_for(hub.changed.wait_for(lambda: hub.version != seen or not hub.open),
                                           KEEPALIVE_S)
                except asyncio.TimeoutError:
                    await resp.write(b": keepalive\n\n")
    except (ConnectionResetError, asyncio.CancelledError):
        pass
    return resp


async def machines(request):
    return web.json_response(request.app[WORKSHOP].machines)


async def plans(request):
    ws = request.app[WORKSHOP]
    return web.json_response({"plans": [ws.plans.info(n) for n in ws.plans.names()],
                              "pictures": ws.plans.picture_names(), "folder": str(ws.folder),
                              "version": ws.plans_version})


async def plan_info(request):
    return web.json_response(request.app[WORKSHOP].plans.info(request.match_info["name"]))


async def plan_drawing(request):
    return web.json_response(request.app[WORKSHOP].plans.drawing(request.match_info["name"]))


async def plan_preview(request):
    path = request.app[WORKSHOP].plans.preview(request.match_info["name"])
    return web.FileResponse(path, headers={"Cache-Control": "no-cache"})


async def _form(request):
    """The request's fields: a JSON object, or a form (multipart: with a picture)."""
    if request.content_type == "application/json":
        body = await request.json()
        if not isinstance(body, dict):
            raise BadInput("the request's body is a JSON " + type(body).__name__ + "; expected an object")
        return body, None
    form, upload = {}, None
    if request.content_type.startswith("multipart/"):
        reader = await request.multipart()
        while (part := await reader.next()) is not None:
            if part.name == "picture" and part.filename:
                upload = (part.filename, await part.read())
            else:
                form[part.name] = (await part.text()).strip()
    else:
        form = {k: v.strip() for k, v in (await request.post()).items() if isinstance(v, str)}
    return form, upload


async def plan_new(request):
    form, upload = await _form(request)
    return web.json_response(await request.app[WORKSHOP].plan(form, upload))


async def command(request):
    """The command line a form would run (the page shows it before anything runs)."""
    form, _ = await _form(request)
    ws = request.app[WORKSHOP]
    action = form.get("action")
    if action == "plan":
        picture = form.get("picture") or "PICTURE"
        picture = picture if "/" in picture else f"pictures/{picture}"
        cmd, _ = plan_command(ws.folder, form, picture)
    elif action in ("wind", "resume"):
        target = parse_target(form.get("target"))
        machine = form.get("machine") or "MACHINE"
        cmd = wind_command(ws.folder, plan_name=form.get("plan") or "PLAN", machine=machine, target=target,
                           port=form.get("port") or ("PORT" if target is Target.PORT else None),
                           faults=form.get("faults"), realtime=str(form.get("realtime")).lower() in ("1", "true", "on"),
                           resume=action == "resume")
    elif action == "check":
        target = parse_target(form.get("target"))
        machine = form.get("machine") or "MACHINE"
        port = form.get("port") or "PORT" if target is Target.PORT else ws.sims.port(machine)
        cmd = check_command(ws.folder, machine=machine, target=target, port=port)
    else:
        raise BadInput(f"action {action!r}; expected plan, wind, resume or check")
    return web.json_response({"command": cmd.shown(), "cwd": str(ws.folder)})


async def check(request):
    form, _ = await _form(request)
    return web.json_response(await request.app[WORKSHOP].check(form))


async def wind(request):
    form, _ = await _form(request)
    return web.json_response(await request.app[WORKSHOP].wind(form))


async def answer(request):
    form, _ = await _form(request)
    return web.json_response(await request.app[WORKSHOP].answer(request.match_info["machine"], form))


async def stop(request):
    return web.json_response(request.app[WORKSHOP].stop(request.match_info["machine"]))


def make_app(folder):
    """The workshop's aiohttp application over the plans folder ``folder`` (a Path that exists)."""
    app = web.Application(middlewares=[_errors], client_max_size=80 * 1024 * 1024)
    workshop = Workshop(folder)
    app[WORKSHOP] = workshop
    hub = _Hub(workshop)
    app[HUB] = hub

    async def on_startup(app):
        workshop.start()
        hub.start()

    async def on_shutdown(app):
        await hub.stop()
        await workshop.close()

    app.on_startup.append(on_startup)
    app.on_shutdown.append(on_shutdown)
    app.add_routes([
        web.get("/", index), web.get("/static/{name}", static),
        web.get("/api/state", state), web.get("/api/events", events), web.get("/api/machines", machines),
        web.get("/api/plans", plans), web.post("/api/plans", plan_new),
        web.get("/api/plans/{name}", plan_info), web.get("/api/plans/{name}/drawing", plan_drawing),
        web.get("/plans/{name}/preview.png", plan_preview),
        web.post("/api/command", command), web.post("/api/check", check), web.post("/api/wind", wind),
        web.post("/api/windings/{machine}/answer", answer), web.post("/api/windings/{machine}/stop", stop),
    ])
    return app
