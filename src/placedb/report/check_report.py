#!/usr/bin/python3
"""Check an HTML report in headless Chromium, as a person would see it.

Opens a local HTML file in Debian's headless Chromium, driven over the Chrome
DevTools Protocol on --remote-debugging-pipe (fd 3 = commands to Chromium,
fd 4 = responses and events from it, each message JSON ended by a NUL byte),
and checks that:

  1. the page loads (load event) within --timeout seconds of being opened;
  2. nothing is logged as an error: uncaught exceptions, console.error /
     console.assert, and Log entries of level error (failed resource loads);
  3. the page is self-contained: every request is data:, about:, blob: or
     file: inside the report's own folder (the report must open offline);
  4. every <figure class="placedb-figure" id="..."> holds at least one <img>,
     and each such img is complete, has a non-zero natural size and a
     non-zero rendered box; --expect ID names figures that must exist and
     --min-figures N the least number of them;

and optionally saves a full-page screenshot (--screenshot) and the DOM as it
stands after loading (--dom-dump).

Three limits, each a parameter, so that a slow start of Chromium on a busy
machine is never mistaken for a page that does not load:
  --startup-timeout  Chromium starts and opens a blank page (default 60 s);
  --timeout          the page loads, with its images, counted from the moment
                     it is opened, after start-up (default 60 s);
  --answer-timeout   each DevTools answer after the load: scripts evaluated in
                     the page, the screenshot (default 60 s).
Whatever hangs, a watchdog ends the run after the sum of the limits.

Exit status: 0 when every check passes, 1 otherwise (one "FAIL: ..." line
per problem), also when the file or Chromium is missing or time runs out;
2 for a bad command line.  Python 3 standard library only; run it with
/usr/bin/python3.  No network port is opened, and Chromium is pointed at a
dead loopback proxy so that nothing the page asks for leaves the machine.
"""

import argparse
import fcntl
import json
import os
import queue
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import urllib.parse
import urllib.request

DEFAULT_CHROMIUM = "/usr/bin/chromium"
FIGURE_SELECTOR = "figure.placedb-figure"
ALLOWED_SCHEMES = ("data", "about", "blob")
STRAY_LIMIT = 60.0  # seconds to wait for killed processes to be gone

# Flags needed on this machine:
# without the background-networking ones Chromium makes connections of its
# own that the closed network refuses.  The dead proxy and the resolver rule
# keep any request the page makes from leaving the machine.
CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--no-default-browser-check",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
    "--disable-extensions",
    "--disable-breakpad",
    "--disable-crash-reporter",
    "--disable-default-apps",
    "--disable-domain-reliability",
    "--metrics-recording-only",
    "--mute-audio",
    "--hide-scrollbars",
    "--proxy-server=http://127.0.0.1:9",
    "--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE localhost",
    "--remote-debugging-pipe",
]

# Evaluated in the page: the figures and their images.
FIGURES_JS = """
(() => Array.from(document.querySelectorAll(%s)).map((f, i) => ({
  index: i,
  id: f.id,
  imgs: Array.from(f.querySelectorAll('img')).map(img => {
    const r = img.getBoundingClientRect();
    return {src: img.currentSrc || img.getAttribute('src') || '',
            complete: img.complete,
            nw: img.naturalWidth, nh: img.naturalHeight,
            w: r.width, h: r.height};
  }),
})))()
""" % json.dumps(FIGURE_SELECTOR)

# Evaluated in the page: true once every image has finished (loaded or
# failed).  Lazy images are made eager: a person would scroll to them.
IMAGES_DONE_JS = """
(() => {
  const imgs = Array.from(document.images);
  for (const img of imgs) if (img.loading === 'lazy') img.loading = 'eager';
  return imgs.every(img => img.complete);
})()
"""


class CheckError(Exception):
    """A problem that ends the check early (one line)."""


class Chromium:
    """One headless Chromium spoken to over --remote-debugging-pipe."""

    def __init__(self, binary, width, height, log_path, user_data_dir):
        self.events = []          # (sessionId, method, params), in order
        self.on_event = None      # called with each event as it comes
        self._inbox = queue.Queue()
        self._next_id = 0
        self._responses = {}
        self._closed = False
        # Move the pipe ends well above 4 so that dup2 onto 3 and 4 in the
        # child cannot clobber one with the other.
        cmd_r, cmd_w = os.pipe()
        resp_r, resp_w = os.pipe()
        child_cmd = fcntl.fcntl(cmd_r, fcntl.F_DUPFD_CLOEXEC, 10)
        child_resp = fcntl.fcntl(resp_w, fcntl.F_DUPFD_CLOEXEC, 10)
        os.close(cmd_r)
        os.close(resp_w)

        def in_child():
            os.dup2(child_cmd, 3)   # Chromium reads commands here
            os.dup2(child_resp, 4)  # and writes responses and events here

        args = [binary] + CHROMIUM_FLAGS + [
            "--user-data-dir=" + user_data_dir,
            "--window-size=%d,%d" % (width, height),
            "about:blank",
        ]
        # HOME and the XDG folders inside the temp folder: Chromium and its
        # crash handler write nothing under the real home, and the crash
        # handler (which detaches into a session of its own) is findable by
        # the temp folder's name in its command line.
        home = os.path.dirname(user_data_dir)
        env = dict(os.environ, HOME=home,
                   XDG_CONFIG_HOME=os.path.join(home, ".config"),
                   XDG_CACHE_HOME=os.path.join(home, ".cache"))
        self._log = open(log_path, "wb")
        try:
            self.proc = subprocess.Popen(
                args, stdin=subprocess.DEVNULL, stdout=self._log,
                stderr=self._log, pass_fds=(3, 4), preexec_fn=in_child,
                start_new_session=True, cwd=home, env=env)
        finally:
            os.close(child_cmd)
            os.close(child_resp)
            self._log.close()
        self._cmd = cmd_w
        self._resp = resp_r
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self):
        buf = b""
        try:
            while True:
                chunk = os.read(self._resp, 1 << 20)
                if not chunk:
                    break
                buf += chunk
                while True:
                    end = buf.find(b"\0")
                    if end < 0:
                        break
                    raw, buf = buf[:end], buf[end + 1:]
                    try:
                        self._inbox.put(json.loads(raw.decode("utf-8")))
                    except ValueError:
                        pass
        except OSError:
            pass
        self._inbox.put(None)

    def _take(self, deadline):
        """Handle one incoming message; False if none came by deadline."""
        left = deadline - time.monotonic()
        if left <= 0:
            return False
        try:
            msg = self._inbox.get(timeout=min(left, 0.25))
        except queue.Empty:
            return True
        if msg is None:
            self._closed = True
            raise CheckError("Chromium closed the DevTools pipe (it exited "
                             "or crashed)")
        if "id" in msg:
            self._responses[msg["id"]] = msg
        elif "method" in msg:
            event = (msg.get("sessionId"), msg["method"],
                     msg.get("params", {}))
            self.events.append(event)
            if self.on_event:
                self.on_event(*event)
        return True

    def send(self, method, params=None, session=None):
        self._next_id += 1
        msg = {"id": self._next_id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        data = json.dumps(msg).encode("utf-8") + b"\0"
        try:
            while data:
                data = data[os.write(self._cmd, data):]
        except OSError as e:
            raise CheckError("cannot write to Chromium's DevTools pipe: %s"
                             % e)
        return self._next_id

    def call(self, method, params=None, session=None, deadline=None,
             limit="30s"):
        """Send a command and wait for its answer; return its result.

        deadline is a time.monotonic() value; limit names it in the error
        (which option ran out).
        """
        if deadline is None:
            deadline = time.monotonic() + 30.0
        cid = self.send(method, params, session)
        while cid not in self._responses:
            if self._closed:
                raise CheckError("Chromium closed the DevTools pipe")
            if not self._take(deadline):
                hint = " (is a script on the page stuck?)" \
                    if method == "Runtime.evaluate" else ""
                raise CheckError("timeout: Chromium did not answer %s "
                                 "within %s%s" % (method, limit, hint))
        resp = self._responses.pop(cid)
        if "error" in resp:
            raise CheckError("%s failed: %s" % (
                method, resp["error"].get("message", resp["error"])))
        return resp.get("result", {})

    def pump(self, deadline, until=None):
        """Handle messages until deadline, or until until() is true."""
        while not (until and until()):
            if not self._take(deadline):
                return False
        return True

    def close(self, grace=3.0):
        """Ask Chromium to quit, then kill its whole process group."""
        proc = self.proc
        if proc.poll() is None and not self._closed:
            try:
                self.send("Browser.close")
            except CheckError:
                pass
            try:
                proc.wait(timeout=grace)
            except subprocess.TimeoutExpired:
                pass
        kill_group(proc)
        for fd in (self._cmd, self._resp):
            try:
                os.close(fd)
            except OSError:
                pass


def kill_group(proc):
    """SIGKILL the process group Chromium leads (it and all its helpers)."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        pass


def kill_strays(marker):
    """SIGKILL this run's processes outside Chromium's process group.

    Chromium's crash handler puts itself in a session of its own; it is
    recognised by this run's unique temp folder in its command line.
    """
    marker = marker.encode()
    me = os.getpid()
    # Until none is left: a killed process leaves /proc (or becomes a zombie
    # with an empty command line) as soon as the kernel has torn it down,
    # which takes longer on a busy machine; the limit only guards a hang.
    until = time.monotonic() + STRAY_LIMIT
    while True:
        found = False
        for name in os.listdir("/proc"):
            if not name.isdigit() or int(name) == me:
                continue
            try:
                with open("/proc/%s/cmdline" % name, "rb") as f:
                    cmdline = f.read()
            except OSError:
                continue
            if marker in cmdline:
                found = True
                try:
                    os.kill(int(name), signal.SIGKILL)
                except OSError:
                    pass
        if not found or time.monotonic() >= until:
            return
        time.sleep(0.05)


def remove_tree(path):
    """Remove a folder; again if a dying process still wrote into it."""
    until = time.monotonic() + STRAY_LIMIT
    while True:
        shutil.rmtree(path, ignore_errors=True)
        if not os.path.lexists(path) or time.monotonic() >= until:
            return
        time.sleep(0.05)


def short(text, limit=200):
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[:limit - 3] + "..."


def remote_object_text(obj):
    if "value" in obj:
        v = obj["value"]
        return v if isinstance(v, str) else json.dumps(v)
    if "unserializableValue" in obj:
        return obj["unserializableValue"]
    return obj.get("description", obj.get("type", "?"))


def where(url, line):
    if not url:
        return ""
    if url.startswith("data:"):
        url = url[:40] + "..."
    return " (%s%s)" % (url, ":%d" % (line + 1) if line is not None else "")


def file_url_inside(url, folder):
    """Whether a file: URL names something inside folder (a real path)."""
    parts = urllib.parse.urlsplit(url)
    if parts.netloc not in ("", "localhost"):
        return False
    path = os.path.realpath(urllib.request.url2pathname(parts.path))
    return path == folder or path.startswith(folder.rstrip(os.sep) + os.sep)


class Report:
    """What the page did, turned into lines of output."""

    def __init__(self, folder):
        self.folder = folder
        self.sessions = set()   # the page's session and those it started
        self.problems = []
        self._seen = set()
        self._done = 0      # events already looked at

    def fail(self, text):
        line = short(text, 400)
        if line not in self._seen:
            self._seen.add(line)
            self.problems.append(line)

    def scan(self, events):
        for sid, method, p in events[self._done:]:
            self._event(sid, method, p)
        self._done = len(events)

    def _event(self, sid, method, p):
        if method in ("Inspector.targetCrashed", "Target.targetCrashed"):
            self.fail("the page crashed")
            return
        if sid not in self.sessions:
            return
        if method == "Target.attachedToTarget":
            self.sessions.add(p.get("sessionId"))
        elif method == "Runtime.exceptionThrown":
            d = p.get("exceptionDetails", {})
            exc = d.get("exception") or {}
            text = (exc.get("description") or "").split("\n")[0] \
                or d.get("text", "exception")
            self.fail("uncaught exception: %s%s" % (
                text, where(d.get("url"), d.get("lineNumber"))))
        elif method == "Runtime.consoleAPICalled":
            if p.get("type") in ("error", "assert"):
                text = " ".join(remote_object_text(a)
                                for a in p.get("args", []))
                if p.get("type") == "assert":
                    text = "assertion failed: " + (text or "console.assert")
                frames = (p.get("stackTrace") or {}).get("callFrames") or []
                loc = where(frames[0].get("url"), frames[0].get(
                    "lineNumber")) if frames else ""
                self.fail("console.%s: %s%s" % (p["type"], text, loc))
        elif method == "Log.entryAdded":
            e = p.get("entry", {})
            if e.get("level") == "error":
                self.fail("console error (%s): %s%s" % (
                    e.get("source", "?"), e.get("text", ""),
                    where(e.get("url"), e.get("lineNumber"))))
        elif method == "Network.requestWillBeSent":
            url = p.get("request", {}).get("url", "")
            scheme = url.split(":", 1)[0].lower()
            if scheme in ALLOWED_SCHEMES:
                return
            if scheme == "file":
                if not file_url_inside(url, self.folder):
                    self.fail("request outside the report's folder: %s"
                              % short(url))
                return
            self.fail("network request (the report must open offline): %s"
                      % short(url))
        elif method == "Network.webSocketCreated":
            self.fail("WebSocket (the report must open offline): %s"
                      % short(p.get("url", "")))


def fmt_size(w, h):
    return "%gx%g" % (round(w, 1), round(h, 1))


def check_figures(figures, expect, min_figures, fail):
    """Print one line per figure; report every problem through fail."""
    ids = {}
    for f in figures:
        fid = f["id"] or "#%d (no id)" % (f["index"] + 1)
        if not f["id"]:
            fail("figure %d has no id" % (f["index"] + 1))
        elif fid in ids:
            fail("figure id %s is used twice" % fid)
        ids[fid] = f
        imgs = f["imgs"]
        if not imgs:
            print("figure %s: no <img>" % fid)
            fail("figure %s has no <img>" % fid)
            continue
        rendered = ", ".join(fmt_size(i["w"], i["h"]) for i in imgs)
        natural = ", ".join(fmt_size(i["nw"], i["nh"]) for i in imgs)
        print("figure %s: rendered %s, natural %s" % (fid, rendered,
                                                      natural))
        for n, img in enumerate(imgs):
            what = "figure %s img %d (%s)" % (fid, n + 1, short(img["src"],
                                                                 80))
            if not img["complete"]:
                fail("%s did not finish loading" % what)
            elif img["nw"] <= 0 or img["nh"] <= 0:
                fail("%s is broken (natural size %s)" % (
                    what, fmt_size(img["nw"], img["nh"])))
            if img["w"] <= 0 or img["h"] <= 0:
                fail("%s is not shown (rendered size %s)" % (
                    what, fmt_size(img["w"], img["h"])))
    for fid in expect:
        if fid not in ids:
            fail("expected figure %s is missing" % fid)
    if len(figures) < min_figures:
        fail("%d figure(s), expected at least %d" % (len(figures),
                                                    min_figures))


def run_check(args, html, tmp, holder):
    folder = os.path.dirname(html)
    url = urllib.parse.urljoin("file:", urllib.request.pathname2url(html))
    browser = Chromium(args.chromium, args.width, args.height,
                       os.path.join(tmp, "chromium.log"),
                       os.path.join(tmp, "profile"))
    holder["proc"] = browser.proc
    report = Report(folder)
    try:
        return drive(browser, report, args, url)
    except CheckError as e:
        log = tail(os.path.join(tmp, "chromium.log"))
        if log and browser.proc.poll() is not None:
            e = "%s [chromium said: %s]" % (e, log)
        report.scan(browser.events)
        return None, [str(e)] + report.problems
    finally:
        browser.close()


def tail(path, limit=300):
    """The last line of Chromium's log that is not its usual D-Bus noise."""
    try:
        with open(path, "rb") as f:
            lines = [l.strip() for l in f.read().decode(
                "utf-8", "replace").splitlines()
                if l.strip() and "dbus" not in l]
    except OSError:
        return ""
    return short(lines[-1], limit) if lines else ""


def drive(browser, report, args, url):
    # Start-up: Chromium starts, opens a blank page and is attached to it,
    # all within --startup-timeout (its first answer says it is up).  The
    # page's own --timeout starts only when the page is opened.
    started = time.monotonic()
    up = started + args.startup_timeout
    up_limit = "--startup-timeout (%gs)" % args.startup_timeout
    version = browser.call("Browser.getVersion", deadline=up, limit=up_limit)
    target = browser.call("Target.createTarget", {"url": "about:blank"},
                          deadline=up, limit=up_limit)["targetId"]
    session = browser.call("Target.attachToTarget",
                           {"targetId": target, "flatten": True},
                           deadline=up, limit=up_limit)["sessionId"]
    report.sessions.add(session)
    page_sessions = {session}
    state = {"loaded": False}

    def follow(sid, method, p):
        if method == "Page.loadEventFired" and sid == session:
            state["loaded"] = True
        # A worker or out-of-process frame the page started: watch it too,
        # then let it run (it waits for us so that nothing is missed).
        if method == "Target.attachedToTarget" and sid in page_sessions:
            child = p["sessionId"]
            page_sessions.add(child)
            for domain in ("Runtime", "Log", "Network"):
                browser.send(domain + ".enable", session=child)
            browser.send("Target.setAutoAttach", {
                "autoAttach": True, "waitForDebuggerOnStart": True,
                "flatten": True}, session=child)
            browser.send("Runtime.runIfWaitingForDebugger", session=child)
    browser.on_event = follow
    for domain in ("Page", "Runtime", "Log", "Network"):
        browser.call(domain + ".enable", session=session, deadline=up,
                     limit=up_limit)
    browser.call("Target.setAutoAttach", {
        "autoAttach": True, "waitForDebuggerOnStart": True,
        "flatten": True}, session=session, deadline=up, limit=up_limit)
    browser.call("Emulation.setDeviceMetricsOverride", {
        "width": args.width, "height": args.height,
        "deviceScaleFactor": 1, "mobile": False}, session=session,
        deadline=up, limit=up_limit)
    # about:blank's events are not the report's (keep the attachments).
    browser.events[:] = [e for e in browser.events
                         if e[1] == "Target.attachedToTarget"]

    start = time.monotonic()
    load_deadline = start + args.timeout
    load_limit = "--timeout (%gs)" % args.timeout
    nav = browser.call("Page.navigate", {"url": url}, session=session,
                       deadline=load_deadline, limit=load_limit)
    if nav.get("errorText"):
        report.scan(browser.events)
        return None, ["cannot open %s: %s" % (url, nav["errorText"])] + \
            report.problems
    state["loaded"] = False
    if not browser.pump(load_deadline, lambda: state["loaded"]):
        report.scan(browser.events)
        return None, ["timeout: no load event within %gs" % args.timeout] + \
            report.problems
    print("loaded in %.2fs (%s, started in %.2fs)" % (
        time.monotonic() - start, version.get("product", "?"),
        start - started))
    sys.stdout.flush()

    # After load: let late scripts run, then wait for every image.  Each
    # DevTools answer from here on has --answer-timeout.
    browser.pump(min(load_deadline, time.monotonic() + args.settle))
    answer_limit = "--answer-timeout (%gs)" % args.answer_timeout

    def late():
        return time.monotonic() + args.answer_timeout
    while True:
        done = browser.call("Runtime.evaluate", {
            "expression": IMAGES_DONE_JS, "returnByValue": True},
            session=session, deadline=late(), limit=answer_limit)
        if done.get("result", {}).get("value") is True:
            break
        if time.monotonic() >= load_deadline:
            report.fail("timeout: images still loading after %gs"
                        % args.timeout)
            break
        browser.pump(min(load_deadline, time.monotonic() + 0.2))
    browser.pump(time.monotonic() + 0.1)

    res = browser.call("Runtime.evaluate", {
        "expression": FIGURES_JS, "returnByValue": True},
        session=session, deadline=late(), limit=answer_limit)
    if "exceptionDetails" in res:
        raise CheckError("cannot read the figures: %s" % short(
            res["exceptionDetails"].get("text")))
    figures = res.get("result", {}).get("value") or []
    check_figures(figures, args.expect, args.min_figures, report.fail)

    if args.dom_dump:
        dom = browser.call("Runtime.evaluate", {
            "expression": "'<!DOCTYPE html>\\n' + "
                          "document.documentElement.outerHTML",
            "returnByValue": True}, session=session, deadline=late(),
            limit=answer_limit)
        with open(args.dom_dump, "w", encoding="utf-8") as f:
            f.write(dom.get("result", {}).get("value", ""))
        print("dom dump: %s" % args.dom_dump)
    if args.screenshot:
        screenshot(browser, session, args, late, answer_limit, report.fail)

    browser.pump(time.monotonic() + 0.1)
    report.scan(browser.events)
    return figures, report.problems


def screenshot(browser, session, args, late, limit, fail):
    import base64
    metrics = browser.call("Page.getLayoutMetrics", session=session,
                           deadline=late(), limit=limit)
    size = metrics.get("cssContentSize") or metrics.get("contentSize") or {}
    width = max(1, min(int(round(size.get("width", args.width))),
                       args.max_width))
    full_height = int(round(size.get("height", args.height)))
    height = max(1, min(full_height, args.max_height))
    shot = browser.call("Page.captureScreenshot", {
        "format": "png", "captureBeyondViewport": True, "fromSurface": True,
        "clip": {"x": 0, "y": 0, "width": width, "height": height,
                 "scale": 1}}, session=session, deadline=late(), limit=limit)
    data = base64.b64decode(shot.get("data", ""))
    if not data.startswith(b"\x89PNG\r\n\x1a\n"):
        fail("the screenshot is not a PNG")
        return
    with open(args.screenshot, "wb") as f:
        f.write(data)
    cut = " (cut from %d px high)" % full_height if full_height > height \
        else ""
    print("screenshot: %s (%dx%d%s, %d bytes)" % (
        args.screenshot, width, height, cut, len(data)))


def parse_args(argv):
    p = argparse.ArgumentParser(
        description="Check an HTML report in headless Chromium: it loads, "
                    "logs no error, asks for nothing off the machine, and "
                    "every placedb figure shows an image. Exit 0 if all "
                    "checks pass, 1 if not.")
    p.add_argument("html", help="the report's HTML file")
    p.add_argument("--timeout", type=float, default=60.0,
                   help="seconds for the page to load, with its images, "
                        "from the moment it is opened (default 60)")
    p.add_argument("--startup-timeout", type=float, default=60.0,
                   help="seconds for Chromium to start and open a blank "
                        "page (default 60)")
    p.add_argument("--answer-timeout", type=float, default=60.0,
                   help="seconds for each DevTools answer after the load: "
                        "scripts in the page, the screenshot (default 60)")
    p.add_argument("--screenshot", metavar="PATH",
                   help="save a full-page PNG screenshot here")
    p.add_argument("--dom-dump", metavar="PATH",
                   help="save the DOM after loading here")
    p.add_argument("--expect", metavar="ID", action="append", default=[],
                   help="a figure id that must exist (repeatable)")
    p.add_argument("--min-figures", metavar="N", type=int, default=0,
                   help="the least number of figures (default 0)")
    p.add_argument("--chromium", metavar="PATH", default=DEFAULT_CHROMIUM,
                   help="the browser (default %s)" % DEFAULT_CHROMIUM)
    p.add_argument("--width", type=int, default=1280,
                   help="viewport width in CSS px (default 1280)")
    p.add_argument("--height", type=int, default=800,
                   help="viewport height in CSS px (default 800)")
    p.add_argument("--max-height", type=int, default=12000,
                   help="screenshot height cap in px (default 12000)")
    p.add_argument("--max-width", type=int, default=4000,
                   help="screenshot width cap in px (default 4000)")
    p.add_argument("--settle", type=float, default=0.5,
                   help="seconds to wait after the load event (default 0.5)")
    args = p.parse_args(argv)
    for name in ("timeout", "startup_timeout", "answer_timeout"):
        if not 0 < getattr(args, name) <= 86400:
            p.error("--%s must be in (0, 86400]" % name.replace("_", "-"))
    if not 0 <= args.settle <= 86400:
        p.error("--settle must be in [0, 86400]")
    return args


def main(argv=None):
    args = parse_args(sys.argv[1:] if argv is None else argv)
    html = os.path.realpath(args.html)
    print("check_report: %s" % html)
    sys.stdout.flush()

    def result(problems):
        for line in problems:
            print("FAIL: %s" % line)
        print("check_report: %s" % ("PASS" if not problems else
                                    "FAIL (%d problem%s)" % (
                                        len(problems),
                                        "" if len(problems) == 1 else "s")))
        sys.stdout.flush()
        return 0 if not problems else 1

    if not os.path.isfile(html):
        return result(["file not found: %s" % args.html])
    if not (os.path.isfile(args.chromium) and
            os.access(args.chromium, os.X_OK)):
        return result(["chromium not found: %s (apt-get install chromium)"
                       % args.chromium])

    # SIGTERM/SIGINT/SIGHUP end the check through the finally below.
    def stop(signum, _frame):
        raise KeyboardInterrupt("signal %d" % signum)
    for sig in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, stop)

    tmp = tempfile.mkdtemp(prefix="check_report.")
    os.mkdir(os.path.join(tmp, "profile"))
    # The hard limit: whatever hangs, the whole run is bounded.  The
    # watchdog kills every Chromium process of this run; the pipe then
    # closes and the waits below end.  It is the sum of every limit: start-
    # up, the load, the settling time, and the answers after the load (the
    # image check's last one, the figures, the DOM, two for the screenshot),
    # with a margin for closing Chromium.
    hard = (args.startup_timeout + args.timeout + args.settle +
            5 * args.answer_timeout + 30)
    holder = {}

    def watchdog():
        proc = holder.get("proc")
        if proc is not None:
            holder["fired"] = True
            kill_group(proc)
    timer = threading.Timer(hard, watchdog)
    timer.daemon = True
    timer.start()
    try:
        try:
            _, problems = run_check(args, html, tmp, holder)
        except KeyboardInterrupt as e:
            problems = ["interrupted (%s)" % (e or "Ctrl-C")]
        except OSError as e:
            problems = ["cannot run %s: %s" % (args.chromium, e)]
        if holder.get("fired"):
            problems.insert(0, "timeout: the check took over %gs and "
                               "Chromium was killed" % hard)
    finally:
        timer.cancel()
        proc = holder.get("proc")
        if proc is not None:
            kill_group(proc)
        kill_strays(tmp)
        remove_tree(tmp)
    return result(problems)


if __name__ == "__main__":
    sys.exit(main())
