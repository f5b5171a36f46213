"""The workshop (``stringbot serve``) in a subprocess, and a small HTTP client for its API (stdlib only).

:class:`Server` starts ``stringbot serve --port 0 --plans DIR`` and reads the address it prints;
:class:`Client` posts JSON and multipart forms and waits on ``/api/state``; :func:`two_colour_picture`
draws a picture whose plan in crimson and navy has a spool change.
"""

import json
import os
import signal
import subprocess
import sys
import time
import urllib.error
import urllib.request
import uuid
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
STRINGBOT = [sys.executable, "-m", "stringbot.cli"]


class Server:
    """``stringbot serve`` on a free port over ``plans``."""

    def __init__(self, plans, *, extra=()):
        self.plans = Path(plans)
        self.proc = subprocess.Popen(STRINGBOT + ["serve", "--port", "0", "--plans", str(plans), *extra],
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        line = self.proc.stderr.readline()
        if not line.startswith("workshop: http://"):
            self.proc.kill()
            raise RuntimeError(f"the workshop did not start: {line}{self.proc.stderr.read()}")
        self.url = line.split()[1].rstrip("/")
        self.client = Client(self.url)

    def stop(self, sig=signal.SIGINT, timeout=60):
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        return self.proc.returncode


class HttpError(Exception):
    def __init__(self, status, body):
        super().__init__(f"HTTP {status}: {body}")
        self.status, self.body = status, body


class Client:
    def __init__(self, url):
        self.url = url

    def _open(self, req, timeout=120):
        try:
            with urllib.request.urlopen(req, timeout=timeout) as resp:
                return json.loads(resp.read())
        except urllib.error.HTTPError as exc:
            raise HttpError(exc.code, json.loads(exc.read() or b"{}")) from None

    def get(self, path):
        return self._open(self.url + path)

    def post(self, path, body=None):
        req = urllib.request.Request(self.url + path, data=json.dumps(body or {}).encode(), method="POST",
                                     headers={"Content-Type": "application/json"})
        return self._open(req)

    def upload(self, path, fields, file_field=None, filename=None, data=None):
        boundary = uuid.uuid4().hex
        parts = []
        for k, v in fields.items():
            parts.append(f'--{boundary}\r\nContent-Disposition: form-data; name="{k}"\r\n\r\n{v}\r\n'.encode())
        if file_field is not None:
            parts.append(f'--{boundary}\r\nContent-Disposition: form-data; name="{file_field}"; '
                         f'filename="{filename}"\r\nContent-Type: application/octet-stream\r\n\r\n'.encode()
                         + data + b"\r\n")
        body = b"".join(parts) + f"--{boundary}--\r\n".encode()
        req = urllib.request.Request(self.url + path, data=body, method="POST",
                                     headers={"Content-Type": f"multipart/form-data; boundary={boundary}"})
        return self._open(req, timeout=600)

    def plan(self, picture, **fields):
        picture = Path(picture)
        return self.upload("/api/plans", fields, "picture", picture.name, picture.read_bytes())

    def winding(self, machine):
        return self.get("/api/state")["windings"].get(machine)

    def wait(self, machine, until, timeout=120):
        """Poll the state until ``until(winding)``; returns that winding."""
        deadline = time.monotonic() + timeout
        w = None
        while time.monotonic() < deadline:
            w = self.winding(machine)
            if w is not None and until(w):
                return w
            time.sleep(0.05)
        raise AssertionError(f"the winding did not get there in {timeout} s: {w}")

    def run(self, machine, answer, timeout=180):
        """Answer every question with ``answer(question, winding)`` until the winding ends."""
        deadline = time.monotonic() + timeout
        asked = []
        while time.monotonic() < deadline:
            w = self.wait(machine, lambda w: w["phase"] in ("asking", "ended"), timeout=timeout)
            if w["phase"] == "ended":
                return w, asked
            q = w["question"]
            asked.append(q)
            try:
                self.post(f"/api/windings/{machine}/answer", {"id": q["id"], "value": answer(q, w)})
            except HttpError as exc:     # asked again meanwhile: answer the new question
                if exc.status != 409:
                    raise
        raise AssertionError("the winding did not end")


def yes(question, winding):
    return True


def two_colour_picture(path):
    """A white picture with a crimson and a navy disc: planned in crimson and navy it has two runs."""
    from PIL import Image, ImageDraw

    im = Image.new("RGB", (300, 300), "white")
    d = ImageDraw.Draw(im)
    d.ellipse((40, 40, 160, 260), fill=(200, 20, 40))
    d.ellipse((150, 60, 270, 240), fill=(20, 40, 160))
    im.save(path)
    return path


def record(plans, machine="grbl-ring"):
    return json.loads((Path(plans) / "simulator" / f"{machine}-record.json").read_text())


def plan_doc(plans, name):
    return json.loads((Path(plans) / f"{name}.json").read_text())


def sequence(doc):
    if "layers" in doc:
        return [p for lay in doc["layers"] for p in lay["sequence"]]
    return doc["sequence"]


def alive(pid):
    try:
        os.kill(pid, 0)
    except OSError:
        return False
    return True
