#!/usr/bin/python3
"""Tests of check_report.py: small HTML pages checked in headless Chromium.

Run with:  /usr/bin/python3 src/placedb/report/check_report_test.py

Each page is checked by running check_report.py as a person would, in its
own process; the Chromium runs go two at a time (the machine has two cores)
in setUpClass, and each test then reads its run's exit code and output.
The runs get a private TMPDIR, so the test can also see that every run
removed its temp folder and left no Chromium process behind.

Nothing here depends on how fast the machine is: Chromium's start-up has a
limit of its own (--startup-timeout), separate from the page's --timeout, and
the timeout cases use pages that can never load (a script fetched from a
socket of this test that accepts and never answers, and a script that never
ends), so that their outcome is the same however slowly Chromium starts.
Every other limit is generous: it only ends a run that hangs.
"""

import base64
import concurrent.futures
import os
import shutil
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
import unittest
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
SCRIPT = os.path.join(HERE, "check_report.py")
PYTHON = "/usr/bin/python3" if os.path.exists("/usr/bin/python3") \
    else sys.executable
CHROMIUM = "/usr/bin/chromium"
# Generous limits, the same for every run: start-up and each DevTools answer
# (a busy machine can take long to start Chromium).  They only end a run that
# hangs, and no outcome below depends on them.
STARTUP = 120
ANSWER = 60
# Seconds: a run that takes longer has hung (check_report.py's own watchdog,
# the sum of its limits, ends it well before this).
RUN_LIMIT = STARTUP + 60 + 5 * ANSWER + 120

RED = (204, 30, 30)
BLUE = (30, 30, 200)


def make_png(width, height, rgb):
    """A tiny solid-colour RGB PNG, written with zlib and struct only."""
    row = b"\0" + bytes(rgb) * width

    def chunk(kind, data):
        return (struct.pack(">I", len(data)) + kind + data +
                struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))
    return (b"\x89PNG\r\n\x1a\n" +
            chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0,
                                       0, 0)) +
            chunk(b"IDAT", zlib.compress(row * height)) +
            chunk(b"IEND", b""))


def data_url(png):
    return "data:image/png;base64," + base64.b64encode(png).decode()


def decode_png(data):
    """Decode an 8-bit RGB/RGBA, non-interlaced PNG: (w, h, channels, rows).

    Checks the signature and every chunk's CRC; rows are bytes objects.
    """
    if not data.startswith(b"\x89PNG\r\n\x1a\n"):
        raise ValueError("no PNG signature")
    pos, idat, ihdr, ended = 8, [], None, False
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        crc, = struct.unpack(">I", data[pos + 8 + length:pos + 12 + length])
        if zlib.crc32(kind + body) & 0xFFFFFFFF != crc:
            raise ValueError("bad CRC in %r chunk" % kind)
        if kind == b"IHDR":
            ihdr = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            ended = True
            break
        pos += 12 + length
    if ihdr is None or not idat or not ended:
        raise ValueError("IHDR, IDAT or IEND missing")
    width, height, depth, colour, _, _, interlace = ihdr
    if depth != 8 or colour not in (2, 6) or interlace:
        raise ValueError("unexpected PNG format %r" % (ihdr,))
    bpp = 3 if colour == 2 else 4
    raw = zlib.decompress(b"".join(idat))
    stride = width * bpp
    if len(raw) != height * (stride + 1):
        raise ValueError("IDAT holds %d bytes, expected %d" % (
            len(raw), height * (stride + 1)))
    rows, prev = [], bytearray(stride)
    for y in range(height):
        ftype = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        if ftype == 1:
            for i in range(bpp, stride):
                line[i] = (line[i] + line[i - bpp]) & 0xFF
        elif ftype == 2:
            line = bytearray((a + b) & 0xFF for a, b in zip(line, prev))
        elif ftype == 3:
            for i in range(stride):
                left = line[i - bpp] if i >= bpp else 0
                line[i] = (line[i] + ((left + prev[i]) >> 1)) & 0xFF
        elif ftype == 4:
            for i in range(stride):
                a = line[i - bpp] if i >= bpp else 0
                b = prev[i]
                c = prev[i - bpp] if i >= bpp else 0
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                line[i] = (line[i] + pred) & 0xFF
        elif ftype != 0:
            raise ValueError("bad filter type %d" % ftype)
        rows.append(bytes(line))
        prev = line
    return width, height, bpp, rows


def count_colour(rows, bpp, rgb, tol=12):
    n = 0
    for row in rows:
        for i in range(0, len(row), bpp):
            if all(abs(row[i + k] - rgb[k]) <= tol for k in range(3)):
                n += 1
    return n


def page(body, title="report"):
    return ('<!DOCTYPE html>\n<html><head><meta charset="utf-8">'
            "<title>%s</title></head><body>\n%s\n</body></html>\n"
            % (title, body))


def figure(fid, inner):
    return '<figure class="placedb-figure" id="%s">%s</figure>' % (fid, inner)


GOOD = page(
    "<h1>placedb report</h1>\n" +
    figure("fig-recall", '<img alt="recall" width="320" src="%s">'
           '<figcaption>recall</figcaption>' % data_url(make_png(64, 48, RED)))
    + "\n" +
    figure("fig-timing", '<img alt="timing" src="%s">'
           '<figcaption>timing</figcaption>'
           % data_url(make_png(40, 20, BLUE))) +
    '\n<div style="height:1500px"></div><p>end of report</p>')

PAGES = {
    "good.html": GOOD,
    "console_error.html": page(
        figure("fig-a", '<img src="%s">' % data_url(make_png(8, 8, RED))) +
        '<script>console.error("something went wrong", 42)</script>'),
    "broken_image.html": page(
        figure("fig-broken", '<img src="missing.png" alt="missing">')),
    "figure_no_img.html": page(
        figure("fig-ok", '<img src="%s">' % data_url(make_png(8, 8, RED))) +
        figure("fig-empty", "<figcaption>no picture here</figcaption>")),
    # Loopback only: the one address a test may ever send to.
    "network.html": page(
        figure("fig-a", '<img src="%s">' % data_url(make_png(8, 8, RED))) +
        '<script src="http://127.0.0.1:9/x.js"></script>'),
    # Never fire the load event: the check must end at --timeout.  A
    # script from a loopback socket of this test that accepts the connection
    # and never answers ({port} is filled in by setUpClass; check_report.py
    # lets Chromium resolve no name but localhost, and localhost is never
    # sent to its dead proxy) ...
    "never_loads.html": page(
        '<script src="http://localhost:{port}/never.js"></script>'),
    # ... and a script that never ends.
    "script_never_ends.html": page("<script>while (true) {}</script>"),
}

# name: (page, extra arguments)
CASES = {
    "good": ("good.html", ["--expect", "fig-recall", "--expect",
                           "fig-timing", "--min-figures", "2",
                           "--screenshot", "{out}/good.png",
                           "--dom-dump", "{out}/good.dom.html"]),
    "console_error": ("console_error.html", []),
    "broken_image": ("broken_image.html", []),
    "figure_no_img": ("figure_no_img.html", []),
    "network": ("network.html", []),
    "expect_missing": ("good.html", ["--expect", "fig-recall", "--expect",
                                     "fig-nowhere", "--min-figures", "3"]),
    "never_loads": ("never_loads.html", ["--timeout", "3"]),
    "script_never_ends": ("script_never_ends.html", ["--timeout", "3"]),
    # These two never start Chromium.
    "missing_file": ("does_not_exist.html", []),
    "missing_chromium": ("good.html", ["--chromium",
                                       "/nonexistent/chromium"]),
}


def run_case(root, name):
    html, extra = CASES[name]
    out = os.path.join(root, "out")
    cmd = [PYTHON, SCRIPT, os.path.join(root, "pages", html),
           "--startup-timeout", str(STARTUP),
           "--answer-timeout", str(ANSWER)] + [
        a.replace("{out}", out) for a in extra]
    env = dict(os.environ, TMPDIR=os.path.join(root, "tmp"))
    start = time.monotonic()
    try:
        proc = subprocess.run(cmd, stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                              env=env, timeout=RUN_LIMIT)
        rc, text = proc.returncode, proc.stdout.decode("utf-8", "replace")
    except subprocess.TimeoutExpired as e:
        rc = "hung"
        text = (e.stdout or b"").decode("utf-8", "replace")
    return rc, text, time.monotonic() - start


class SilentServer:
    """A loopback socket that accepts every connection and never answers:
    a request to it never completes while the server lives."""

    def __init__(self):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(16)
        self.port = self.sock.getsockname()[1]
        self.connections = []
        self.thread = threading.Thread(target=self._accept, daemon=True)
        self.thread.start()

    def _accept(self):
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return  # closed
            self.connections.append(conn)  # held open, never answered

    def close(self):
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self.sock.close()
        self.thread.join()
        for conn in self.connections:
            conn.close()


def processes_mentioning(marker):
    found = []
    for name in os.listdir("/proc"):
        if name.isdigit():
            try:
                with open("/proc/%s/cmdline" % name, "rb") as f:
                    if marker.encode() in f.read():
                        found.append(int(name))
            except OSError:
                pass
    return found


@unittest.skipUnless(os.access(CHROMIUM, os.X_OK),
                     "%s is not installed (apt-get install chromium)"
                     % CHROMIUM)
class CheckReportTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        cls.root = tempfile.mkdtemp(prefix="check_report_test.")
        for sub in ("pages", "out", "tmp"):
            os.mkdir(os.path.join(cls.root, sub))
        cls.server = SilentServer()
        for name, text in PAGES.items():
            with open(os.path.join(cls.root, "pages", name), "w",
                      encoding="utf-8") as f:
                f.write(text.replace("{port}", str(cls.server.port)))
        start = time.monotonic()
        with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
            futures = {name: pool.submit(run_case, cls.root, name)
                       for name in CASES}
            cls.results = {name: f.result() for name, f in futures.items()}
        cls.wall = time.monotonic() - start
        cls.server.close()
        # Every run must have removed its temp folder and its processes.
        cls.tmp_left = os.listdir(os.path.join(cls.root, "tmp"))
        cls.procs_left = processes_mentioning(os.path.join(cls.root, "tmp"))
        if os.environ.get("CHECK_REPORT_TEST_VERBOSE"):
            for name, (rc, text, secs) in cls.results.items():
                sys.stderr.write("--- %s: exit %s in %.2fs\n%s" % (
                    name, rc, secs, text))
            sys.stderr.write("--- all runs: %.2fs wall\n" % cls.wall)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.root, ignore_errors=True)

    def result(self, name, want_rc):
        rc, text, secs = self.results[name]
        self.assertEqual(rc, want_rc, "exit %s for %s:\n%s" % (rc, name,
                                                              text))
        last = text.strip().splitlines()[-1]
        self.assertEqual(last.startswith("check_report: PASS"), want_rc == 0,
                         text)
        return text

    def fail_lines(self, text):
        return [l for l in text.splitlines() if l.startswith("FAIL: ")]

    def test_good_page_passes(self):
        text = self.result("good", 0)
        self.assertEqual(self.fail_lines(text), [], text)
        self.assertIn("figure fig-recall: rendered 320x240, natural 64x48",
                      text)
        self.assertIn("figure fig-timing: rendered 40x20, natural 40x20",
                      text)

    def test_good_page_screenshot(self):
        self.result("good", 0)
        path = os.path.join(self.root, "out", "good.png")
        self.assertGreater(os.path.getsize(path), 0)
        with open(path, "rb") as f:
            data = f.read()
        width, height, bpp, rows = decode_png(data)
        self.assertEqual(width, 1280)
        # The whole page, not the 800 px viewport.
        self.assertGreater(height, 1500)
        self.assertLessEqual(height, 12000)
        # The figures are really drawn: 320x240 red, 40x20 blue.
        self.assertGreater(count_colour(rows[:600], bpp, RED), 320 * 240 * 0.9)
        self.assertGreater(count_colour(rows[:600], bpp, BLUE), 40 * 20 * 0.9)

    def test_good_page_dom_dump(self):
        self.result("good", 0)
        with open(os.path.join(self.root, "out", "good.dom.html"),
                  encoding="utf-8") as f:
            dom = f.read()
        self.assertTrue(dom.startswith("<!DOCTYPE html>"), dom[:80])
        self.assertIn('id="fig-recall"', dom)
        self.assertIn("end of report", dom)

    def test_console_error_fails(self):
        text = self.result("console_error", 1)
        self.assertIn("FAIL: console.error: something went wrong 42", text)

    def test_broken_image_fails(self):
        text = self.result("broken_image", 1)
        self.assertIn("figure fig-broken img 1", text)
        self.assertIn("is broken (natural size 0x0)", text)
        # The failed load is a console error too.
        self.assertIn("ERR_FILE_NOT_FOUND", text)
        self.assertIn("missing.png", text)

    def test_figure_without_img_fails(self):
        text = self.result("figure_no_img", 1)
        self.assertEqual(self.fail_lines(text),
                         ["FAIL: figure fig-empty has no <img>"], text)
        self.assertIn("figure fig-ok: rendered 8x8, natural 8x8", text)

    def test_network_request_fails(self):
        text = self.result("network", 1)
        self.assertIn("FAIL: network request (the report must open "
                      "offline): http://127.0.0.1:9/x.js", text)

    def test_expected_figures(self):
        text = self.result("expect_missing", 1)
        self.assertEqual(self.fail_lines(text), [
            "FAIL: expected figure fig-nowhere is missing",
            "FAIL: 2 figure(s), expected at least 3"], text)

    def timed_out_loading(self, name):
        text = self.result(name, 1)
        # The page's own limit ran out, not start-up's, and the run ended by
        # itself (not by the watchdog).
        self.assertIn("FAIL: timeout: no load event within 3s", text)
        self.assertNotIn("did not answer", text)
        self.assertNotIn("Chromium was killed", text)
        self.assertNotIn("loaded in", text)
        return text

    def test_page_that_never_loads_times_out(self):
        self.timed_out_loading("never_loads")

    def test_script_that_never_ends_times_out(self):
        self.timed_out_loading("script_never_ends")

    def test_bad_limits_are_refused(self):
        for flag in ("--timeout", "--startup-timeout", "--answer-timeout"):
            for value in ("0", "-1", "nan"):
                proc = subprocess.run(
                    [PYTHON, SCRIPT, "x.html", flag, value],
                    stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                    stdin=subprocess.DEVNULL, timeout=RUN_LIMIT)
                self.assertEqual(proc.returncode, 2, (flag, value))
                self.assertIn(flag, proc.stderr.decode(), (flag, value))

    def test_missing_file(self):
        text = self.result("missing_file", 1)
        self.assertIn("FAIL: file not found:", text)

    def test_missing_chromium(self):
        text = self.result("missing_chromium", 1)
        self.assertIn("FAIL: chromium not found: /nonexistent/chromium",
                      text)

    def test_cleans_up(self):
        self.assertEqual(self.tmp_left, [])
        self.assertEqual(self.procs_left, [])

    def test_no_run_hangs(self):
        for name, (rc, text, secs) in self.results.items():
            self.assertNotEqual(rc, "hung", "%s hung:\n%s" % (name, text))


if __name__ == "__main__":
    unittest.main()
