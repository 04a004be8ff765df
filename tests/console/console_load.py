#!/usr/bin/env python3
"""The console under load (docs/console.md, "Security"): slow-header connections (a
slowloris: a request line and a header, then a byte every 0.5 s, never finished)
neither starve other clients nor live past the request deadline.

* 80 from 127.0.0.1: all but 16 (the per-address cap) are closed at once, and a
  request from 127.0.0.2 is answered within 2 s;
* 80 more from five other addresses (16 each): all stay open (under the cap of 256),
  and a request from a sixth address is answered within 2 s;
* each slow connection is closed by the deadline (--header-timeout) counted from its
  start, although it sends a byte every 0.5 s; a kept-alive connection gets the
  deadline again from its answer; then 127.0.0.1 is answered again;
* a long poll (an answer under way) outlives a deadline shorter than it;
* --header-timeout outside 0.1..3600 is a usage error.

usage: console_load.py KOGEI PARENT_DIR (works in a new directory below it)"""
import http.client
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from console_common import Console, check, failures  # noqa: E402

TIMEOUT = 5.0  # --header-timeout of the console under load
DRIP = 0.5     # s between the slow connections' bytes


class Slow:
    """Slow-header connections: each sends a request line and the start of a header,
    then one byte every DRIP s from a single thread; records when the server closed
    each one (EOF or reset)."""

    def __init__(self, c):
        self.c = c
        self.socks = []  # [socket, opened, closed or None]
        self.lock = threading.Lock()
        self.stop = False
        self.thread = threading.Thread(target=self.drip, daemon=True)
        self.thread.start()

    def open(self, source, n):
        for _ in range(n):
            s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            s.bind((source, 0))
            s.settimeout(5)
            s.connect(("127.0.0.1", self.c.port))
            s.setblocking(False)
            opened = time.monotonic()
            entry = [s, opened, None]
            try:
                s.send(("GET /api/state HTTP/1.1\r\nHost: %s\r\nX-Slow: " %
                        self.c.hostport).encode())
            except OSError:
                entry[2] = opened
            with self.lock:
                self.socks.append(entry)

    def poll(self):
        """Mark the connections the server has closed."""
        now = time.monotonic()
        with self.lock:
            for e in self.socks:
                if e[2] is not None:
                    continue
                try:
                    if e[0].recv(4096) == b"":
                        e[2] = now
                except BlockingIOError:
                    pass
                except OSError:
                    e[2] = now

    def drip(self):
        while not self.stop:
            now = time.monotonic()
            with self.lock:
                for e in self.socks:
                    if e[2] is None:
                        try:
                            e[0].send(b"a")
                        except BlockingIOError:
                            pass
                        except OSError:
                            e[2] = now
            self.poll()
            time.sleep(DRIP)

    def open_count(self, entries=None):
        self.poll()
        with self.lock:
            return sum(1 for e in (entries or self.socks) if e[2] is None)

    def close(self):
        self.stop = True
        self.thread.join()
        for e in self.socks:
            e[0].close()


def timed_get(c, source, path="/api/state", timeout=10):
    """GET from a given source address: (status or an error, seconds)."""
    t0 = time.monotonic()
    try:
        conn = http.client.HTTPConnection("127.0.0.1", c.port, timeout=timeout,
                                          source_address=(source, 0))
        conn.request("GET", path, headers={"Host": c.hostport})
        r = conn.getresponse()
        r.read()
        conn.close()
        return r.status, time.monotonic() - t0
    except OSError as e:
        return "%s" % (e.__class__.__name__,), time.monotonic() - t0


def under_load(kogei, work):
    c = Console(kogei, work + "/L", [], extra=["--header-timeout", str(TIMEOUT)])
    slow = Slow(c)
    try:
        st, dt = timed_get(c, "127.0.0.1")
        check(st == 200, "an unloaded console answers (%s)" % st)
        # 1. 80 slow connections from one address: 16 kept, the others closed at once.
        slow.open("127.0.0.1", 80)
        first = list(slow.socks)
        time.sleep(1.0)
        n_open = slow.open_count(first)
        with slow.lock:
            held = [e for e in first if e[2] is None]
        check(n_open == 16, "80 slow connections from 127.0.0.1: %d stay open (the cap "
              "is 16 per address)" % n_open)
        st, dt = timed_get(c, "127.0.0.2")
        check(st == 200 and dt < 2.0, "with 80 slow connections from 127.0.0.1, 127.0.0.2 "
              "is answered within 2 s (%s in %.2f s)" % (st, dt))
        print("80 slow from 127.0.0.1: %d open; 127.0.0.2 answered %s in %.3f s"
              % (n_open, st, dt))
        # 2. 80 more from five addresses: all kept (96 in all, under 256); others served.
        t_b = time.monotonic()
        for k in range(3, 8):
            slow.open("127.0.0.%d" % k, 16)
        second = slow.socks[80:]
        time.sleep(0.5)
        n_open2 = slow.open_count(second)
        check(n_open2 == 80, "80 slow connections from 5 addresses: all 80 open (%d)" % n_open2)
        st, dt = timed_get(c, "127.0.0.9")
        check(st == 200 and dt < 2.0, "with %d slow connections open, 127.0.0.9 is answered "
              "within 2 s (%s in %.2f s)" % (slow.open_count(), st, dt))
        print("%d slow connections open; 127.0.0.9 answered %s in %.3f s"
              % (slow.open_count(), st, dt))
        # a kept-alive connection: answered, then a slow second request
        ka = http.client.HTTPConnection("127.0.0.1", c.port, timeout=10,
                                        source_address=("127.0.0.10", 0))
        ka.request("GET", "/api/state", headers={"Host": c.hostport})
        r = ka.getresponse()
        r.read()
        t_ka = time.monotonic()
        check(r.status == 200, "a keep-alive request answered (%d)" % r.status)
        ka.sock.send(b"GET /api/state HTTP/1.1\r\nHost: " + c.hostport.encode() + b"\r\nX-Slow:")
        ka.sock.setblocking(False)
        with slow.lock:
            slow.socks.append([ka.sock, t_ka, None])
        # 3. The deadline: every slow connection closed TIMEOUT s after its start.
        deadline = max(t_b, t_ka) + TIMEOUT + 3
        while time.monotonic() < deadline and slow.open_count():
            time.sleep(0.1)
        left = slow.open_count()
        check(left == 0, "every slow connection is closed by the %.0f s deadline although it "
              "sends a byte every %.1f s (%d left)" % (TIMEOUT, DRIP, left))
        with slow.lock:
            ages = [e[2] - e[1] for e in held + slow.socks[80:] if e[2] is not None]
        if check(len(ages) == len(held) + 81, "closing times of the held connections (%d)"
                 % len(ages)):
            check(min(ages) >= TIMEOUT - 0.3 and max(ages) <= TIMEOUT + 1.5,
                  "held slow connections closed %.2f..%.2f s after their start (deadline "
                  "%.1f s)" % (min(ages), max(ages), TIMEOUT))
            print("slow connections closed %.2f..%.2f s after their start (--header-timeout "
                  "%.1f)" % (min(ages), max(ages), TIMEOUT))
        st, dt = timed_get(c, "127.0.0.1")
        check(st == 200 and dt < 2.0, "after the deadline 127.0.0.1 is answered again (%s)" % st)
    finally:
        slow.close()
        rc = c.stop()
        check(rc == 0, "the console stops on SIGTERM with 0 (got %s)" % rc)
        with open(c.log) as f:
            log = f.read()
        check("closed at the request deadline" in log,
              "the console reports the connections it closed: %r" % log[-300:])


def long_poll(kogei, work):
    """An answer under way has no deadline: a 2 s long poll with a 0.5 s deadline."""
    c = Console(kogei, work + "/P", [], extra=["--header-timeout", "0.5"])
    try:
        t0 = time.monotonic()
        st, _ = c.request("GET", "/api/live?after=1000000")
        dt = time.monotonic() - t0
        check(st == 200 and dt > 1.5, "a 2 s long poll outlives a 0.5 s deadline (%d in %.2f s)"
              % (st, dt))
    finally:
        c.stop()


def usage(kogei, work):
    for bad in ("0.05", "3601", "x", "nan"):
        r = subprocess.run([kogei, "console", "--session", work + "/U", "--listen",
                            "127.0.0.1:0", "--header-timeout", bad],
                           capture_output=True, text=True, timeout=20)
        check(r.returncode == 2 and "--header-timeout" in r.stderr,
              "--header-timeout %s: expected exit 2 naming the option (exit %d: %s)"
              % (bad, r.returncode, r.stderr.strip()[:200]))


def main():
    kogei, parent = sys.argv[1:3]
    work = tempfile.mkdtemp(prefix="console-load-", dir=parent)
    usage(kogei, work)
    under_load(kogei, work)
    long_poll(kogei, work)
    print("console-load: %s" % ("FAIL (%d)" % len(failures) if failures else "ok"))
    if not failures:
        shutil.rmtree(work)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
