"""Headless Chromium (Debian's ``chromium`` and ``chromedriver``) driving the workshop page with selenium.

:func:`browser` starts one (skipping the test, with the reason, when Chromium, its driver or selenium
is missing); :class:`Page` clicks the page's buttons and takes full-page screenshots.  With
``STRINGBOT_SCREENSHOTS=docs`` the screenshots are also written to ``docs/workshop-*.png`` (the
README's pictures); otherwise only into the test's folder.
"""

import os
import shutil
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
DRIVER = shutil.which("chromedriver") or "/usr/bin/chromedriver"


def browser():
    """A headless Chromium through selenium, or a skip naming what is missing."""
    try:
        from selenium import webdriver
    except ImportError:
        pytest.skip("selenium is not installed (pip install -e '.[test]')")
    for path, what in ((CHROMIUM, "chromium"), (DRIVER, "chromedriver")):
        if not os.path.exists(path):
            pytest.skip(f"{what} is not installed (apt-get install chromium chromium-driver; .ci/run does)")
    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1440,1000", "--hide-scrollbars", "--force-device-scale-factor=1"):
        opts.add_argument(arg)
    return webdriver.Chrome(service=webdriver.ChromeService(executable_path=DRIVER), options=opts)


class Page:
    """The workshop page in a browser, with the server's API beside it to know what it shows."""

    def __init__(self, driver, server, shots):
        from selenium.webdriver.common.by import By

        self.d, self.server, self.shots, self.By = driver, server, Path(shots), By
        self.d.get(server.url + "/")
        self.wait(lambda: "live" in self.find("#live").get_attribute("class").split()
                  and "on" in self.find("#live").get_attribute("class").split())

    def find(self, css, root=None):
        return (root or self.d).find_element(self.By.CSS_SELECTOR, css)

    def finds(self, css, root=None):
        return (root or self.d).find_elements(self.By.CSS_SELECTOR, css)

    def wait(self, cond, timeout=60, what="the page"):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                if cond():
                    return
            except Exception:           # the element is being re-drawn: look again
                pass
            time.sleep(0.05)
        raise AssertionError(f"{what} did not get there in {timeout} s")

    def select(self, css, value):
        """Choose ``value`` in the ``<select>`` ``css`` once it offers it (the page re-draws its options as
        the state comes in: look again while the element under it is replaced)."""
        from selenium.webdriver.support.ui import Select

        def chosen():
            Select(self.find(css)).select_by_value(value)
            return self.find(css).get_attribute("value") == value
        self.wait(chosen, what=f"{css} offering {value!r}")

    def _again(self, act):
        """``act()``, again while the page re-draws the element under it (a stale reference)."""
        from selenium.common.exceptions import StaleElementReferenceException

        for _ in range(50):
            try:
                return act()
            except StaleElementReferenceException:
                time.sleep(0.05)
        return act()

    def text(self, css):
        """The text of ``css`` (read again while the page re-draws it)."""
        return self._again(lambda: self.find(css).text)

    def type(self, css, text):
        def act():
            el = self.find(css)
            el.clear()
            el.send_keys(text)
        self._again(act)

    def click_text(self, root_css, text):
        """Click the button under ``root_css`` whose text starts with ``text``."""
        def act():
            for b in self.finds(f"{root_css} button"):
                if b.is_displayed() and b.text.strip().startswith(text):
                    b.click()
                    return
            raise AssertionError(f"no button {text!r} in {root_css}: "
                                 + ", ".join(b.text for b in self.finds(f"{root_css} button")))
        self._again(act)

    def card(self, machine):
        return f'.winding[data-machine="{machine}"]'

    def question(self, machine, after=None):
        """The question the page shows now (from the server's state; another than question number
        ``after``) once the page shows it; ``(None, winding)`` when the winding ended."""
        c = self.server.client
        w = c.wait(machine, lambda w: w["phase"] == "ended" or (
            w["phase"] == "asking" and w["question"]["id"] != after))
        if w["phase"] == "ended":
            return None, w
        box = self.card(machine) + " .w-question"
        shown = (w["question"].get("question") or "Guided way back")[:40]
        ask = str(w["question"]["id"])
        self.wait(lambda: self.find(box).is_displayed() and self.find(box).get_attribute("data-ask") == ask
                  and shown in self.find(box).text,
                  what=f"the question {w['question']}")
        return w["question"], w

    def ended(self, machine):
        self.wait(lambda: self.server.client.winding(machine)["phase"] == "ended", timeout=120)
        w = self.server.client.winding(machine)
        self.wait(lambda: (w["outcome"] or "") in self.find(self.card(machine) + " .w-phase").text.lower())
        return w

    def shot(self, name):
        """A screenshot of the whole page (docs/workshop-NAME.png with STRINGBOT_SCREENSHOTS=docs)."""
        time.sleep(0.4)                                  # the last pushed state drawn
        height = self.d.execute_script("return document.documentElement.scrollHeight")
        self.d.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                               {"width": 1440, "height": int(height), "deviceScaleFactor": 1, "mobile": False})
        try:
            path = self.shots / f"workshop-{name}.png"
            self.d.save_screenshot(str(path))
        finally:
            self.d.execute_cdp_cmd("Emulation.clearDeviceMetricsOverride", {})
        if os.environ.get("STRINGBOT_SCREENSHOTS") == "docs":
            shutil.copy(path, ROOT / "docs" / path.name)
        return path

    def errors(self):
        """The browser console's errors (a page that throws fails its test)."""
        return [e for e in self.d.get_log("browser") if e["level"] == "SEVERE" and "favicon" not in e["message"]]
