"""Figures of the workshop page (``stringbot serve``): does the live view keep up?

    python benchmarks/bench_workshop.py [--minutes 60] [--lines auto] [--no-browser]

1. A full-speed dry run of the camera plan on grbl-ring (``--lines``, default the planner's
   own count) with a client on the event stream and the page open in headless Chromium:
   the updates per second the client sees while the winding runs, the longest gap between
   two, and whether the last one shows every step; the browser's CPU (its processes' CPU
   time from /proc over the wall time) while it watches.
2. A real-time winding on the workshop's simulator for ``--minutes`` (default 60), the page
   open all along: the server's resident memory (its own process, /proc) sampled every ten
   seconds, a line every minute, and the slope of a straight line fitted to it (MB per hour;
   no growth is a slope near 0); the browser's CPU over the whole winding; the updates per
   second.  The winding is then paused (the Ctrl-C way) and the server stopped.

The browser needs Debian's chromium and chromedriver and selenium (as the browser tests).
"""

import argparse
import json
import os
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from workshop_helpers import EXAMPLES, Server  # noqa: E402

TICK = os.sysconf("SC_CLK_TCK")


def _stat(pid):
    """(parent pid, CPU seconds) of process ``pid`` from /proc, or None."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = text[text.rindex(")") + 2:].split()
    return int(fields[1]), (int(fields[11]) + int(fields[12])) / TICK


def tree_cpu(root):
    """CPU seconds of ``root`` and every process below it."""
    parents = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            st = _stat(int(entry))
            if st is not None:
                parents[int(entry)] = st
    total, todo = 0.0, [root]
    while todo:
        pid = todo.pop()
        if pid in parents:
            total += parents[pid][1]
        todo += [p for p, (pp, _) in parents.items() if pp == pid]
    return total


def rss_mb(pid):
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


class Watcher(threading.Thread):
    """A client on /api/events: the time of every update and the last state of ``machine``."""

    def __init__(self, url, machine="grbl-ring"):
        super().__init__(daemon=True)
        self.url, self.machine = url, machine
        self.times, self.last = [], None

    def run(self):
        import urllib.request
        with urllib.request.urlopen(self.url + "/api/events", timeout=600) as stream:
            for raw in stream:
                line = raw.decode().strip()
                if line.startswith("data: "):
                    w = json.loads(line[6:])["windings"].get(self.machine)
                    if w is not None:
                        self.times.append(time.monotonic())
                        self.last = w

    def rate(self, t0, t1):
        ts = [t for t in self.times if t0 <= t <= t1]
        gaps = [b - a for a, b in zip(ts, ts[1:])]
        return len(ts) / max(t1 - t0, 1e-9), max(gaps) if gaps else float("inf")


def browser(url):
    from browser_helpers import browser as start

    import pytest
    try:
        d = start()
    except pytest.skip.Exception as exc:
        print(f"no browser: {exc}")
        return None
    d.get(url + "/")
    return d


def chromium_root(driver):
    return driver.service.process.pid if driver is not None else None


def answer_all(client, machine="grbl-ring", until=lambda w: False):
    """Answer yes to the winding's questions until it runs (or ``until``)."""
    while True:
        w = client.winding(machine)
        if w["phase"] == "asking":
            client.post(f"/api/windings/{machine}/answer", {"id": w["question"]["id"], "value": True})
        elif w["phase"] == "ended" or (w["phase"] == "running" and until(w)):
            return w
        time.sleep(0.05)


def dry_run(server, driver, lines):
    c = server.client
    fields = {"name": "cam", "machine": "grbl-ring"}
    if lines != "auto":
        fields["lines"] = lines
    c.plan(EXAMPLES / "camera.png", **fields)
    watch = Watcher(server.url)
    watch.start()
    time.sleep(1.0)
    root = chromium_root(driver)
    if root:
        cpu0 = tree_cpu(root)
        time.sleep(5.0)
        print(f"idle page: the browser {100 * (tree_cpu(root) - cpu0) / 5.0:.1f} % of one core")
    c.post("/api/wind", {"plan": "cam", "machine": "grbl-ring", "target": "dry-run"})
    w = answer_all(c, until=lambda w: w["question"] is None and w["done"] > 0)
    t0, cpu0 = time.monotonic(), tree_cpu(root) if root else 0.0
    while c.winding("grbl-ring")["phase"] != "ended":
        time.sleep(0.05)
    t1 = time.monotonic()
    cpu1 = tree_cpu(root) if root else 0.0
    time.sleep(1.0)
    w = c.winding("grbl-ring")
    rate, gap = watch.rate(t0, t1)
    print(f"dry run: {w['total']} steps in {t1 - t0:.1f} s ({w['total'] / (t1 - t0):.0f} pins/s), "
          f"outcome {w['outcome']}; the event stream: {rate:.1f} updates/s, longest gap {gap:.2f} s; "
          f"its last update shows step {watch.last['done']} of {watch.last['total']}")
    if root:
        page_done = driver.execute_script("return document.querySelector('.winding .w-step').textContent")
        print(f"  browser: {100 * (cpu1 - cpu0) / (t1 - t0):.1f} % of one core while it watched "
              f"(CPU {cpu1 - cpu0:.2f} s in {t1 - t0:.1f} s); the page says step {page_done}")


def real_time(server, driver, minutes):
    c = server.client
    c.plan(EXAMPLES / "camera.png", name="long", machine="grbl-ring")
    watch = Watcher(server.url)
    watch.start()
    c.post("/api/wind", {"plan": "long", "machine": "grbl-ring", "target": "simulator", "realtime": True})
    answer_all(c, until=lambda w: w["question"] is None and w["done"] > 0)
    root = chromium_root(driver)
    t0, cpu0 = time.monotonic(), tree_cpu(root) if root else 0.0
    samples = []
    print("minute  server RSS (MB)  steps done  browser CPU (% of a core, that minute)")
    last_cpu, last_t = cpu0, t0
    while time.monotonic() - t0 < minutes * 60:
        time.sleep(10.0)
        now = time.monotonic()
        samples.append((now - t0, rss_mb(server.proc.pid)))
        if len(samples) % 6 == 0:
            cpu = tree_cpu(root) if root else 0.0
            w = c.winding("grbl-ring")
            print(f"{len(samples) // 6:>6}  {samples[-1][1]:>15.1f}  {w['done']:>10}  "
                  f"{100 * (cpu - last_cpu) / (now - last_t):>6.1f}")
            last_cpu, last_t = cpu, now
            if w["phase"] == "ended":
                print(f"the winding ended: {w['outcome']}")
                break
    t1 = time.monotonic()
    cpu1 = tree_cpu(root) if root else 0.0
    n = len(samples)
    mx = sum(t for t, _ in samples) / n
    my = sum(r for _, r in samples) / n
    slope = sum((t - mx) * (r - my) for t, r in samples) / max(sum((t - mx) ** 2 for t, _ in samples), 1e-9)
    rate, gap = watch.rate(t0, t1)
    print(f"real time, {(t1 - t0) / 60:.1f} min: server RSS {samples[0][1]:.1f} -> {samples[-1][1]:.1f} MB "
          f"(min {min(r for _, r in samples):.1f}, max {max(r for _, r in samples):.1f}); fitted slope "
          f"{slope * 3600:+.2f} MB per hour; the event stream {rate:.2f} updates/s, longest gap {gap:.2f} s")
    if root:
        print(f"  browser: {100 * (cpu1 - cpu0) / (t1 - t0):.1f} % of one core over the winding")
    c.post("/api/windings/grbl-ring/stop")
    w = c.wait("grbl-ring", lambda w: w["phase"] == "ended", timeout=60)
    print(f"paused: {w['outcome']} at step {w['done']} of {w['total']} (journaled; resumable)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, default=60.0, help="length of the real-time winding")
    ap.add_argument("--lines", default="auto", help="lines of the dry run's plan (default: the planner's count)")
    ap.add_argument("--no-browser", action="store_true", help="only the event stream, no Chromium")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench-workshop-") as tmp:
        server = Server(Path(tmp) / "plans")
        driver = None if args.no_browser else browser(server.url)
        try:
            dry_run(server, driver, args.lines)
            if args.minutes > 0:
                real_time(server, driver, args.minutes)
        finally:
            if driver is not None:
                driver.quit()
            server.stop()


if __name__ == "__main__":
    main()
