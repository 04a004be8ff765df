#!/usr/bin/env python3
"""The console under load (docs/console.md, "Security"): connections that hold the
console without using it (slow-header senders, idle and kept-alive idlers, readers that
stop reading an answer) neither starve other clients, the operator's browser on the
same address included, nor live past their deadlines.

* 80 slow-header connections (a request line and a header, then a byte every 0.5 s,
  never finished) from 127.0.0.1: 16 (the per-address cap) stay open, the stalest
  closed as newer ones come, and a request from 127.0.0.2 is answered within 2 s;
* 80 more from five other addresses (16 each): all stay open (under the cap of 256),
  and a request from a sixth address is answered within 2 s;
* each slow connection is closed by the deadline (--header-timeout) counted from its
  start, although it sends a byte every 0.5 s; a kept-alive connection gets the
  deadline again from its answer; then 127.0.0.1 is answered again;
* slow readers: 32 sockets from 127.0.0.1 that ask for a 24 MiB file and never read,
  slow-header senders, idle and kept-alive idle connections from 127.0.0.1, and 32
  more readers arriving halfway: a client on 127.0.0.1 gets >= 38 of 40 requests
  answered, each within 3 s; on an address below its cap, readers that stopped
  (or read 1 KiB/s) are cut off --send-timeout after their answer began, idle and
  slow-header ones --header-timeout after their start; every hostile socket is
  closed by then (seen from the client: its TCP state leaves ESTABLISHED), and a
  reader that keeps reading (3 MB/s) gets the whole file although it takes longer
  than the send deadline;
* a long poll (an answer under way) outlives a deadline shorter than it;
* --header-timeout and --send-timeout outside 0.1..3600 are usage errors.

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
TCP_ESTABLISHED = 1


def server_closed(sock):
    """The server closed this socket (its FIN or reset came): the TCP state, first
    byte of TCP_INFO, has left ESTABLISHED. Needs no read, so a socket that never
    reads what it was sent is seen closed too."""
    try:
        return sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_INFO, 8)[0] != TCP_ESTABLISHED
    except OSError:
        return True


class Slow:
    """Connections that hold the console, driven from one thread; records when the
    server closed each one. Kinds: "drip" sends a request line and the start of a
    header, then a byte every DRIP s; "idle" sends nothing; "reader" asks for `path`
    (its receive buffer small) and never reads; "trickle" asks for `path` and reads
    512 bytes every DRIP s."""

    def __init__(self, c):
        self.c = c
        self.socks = []  # [socket, opened, closed or None, kind]
        self.lock = threading.Lock()
        self.stop = False
        self.thread = threading.Thread(target=self.drip, daemon=True)
        self.thread.start()

    def open(self, source, n, kind="drip", path="/api/state"):
        first = {"drip": "GET /api/state HTTP/1.1\r\nHost: %s\r\nX-Slow: " % self.c.hostport,
                 "idle": "",
                 "reader": "GET %s HTTP/1.1\r\nHost: %s\r\n\r\n" % (path, self.c.hostport)}
        first["trickle"] = first["reader"]
        for _ in range(n):
            s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            if kind in ("reader", "trickle"):
                s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            s.bind((source, 0))
            s.settimeout(5)
            s.connect(("127.0.0.1", self.c.port))
            s.setblocking(False)
            opened = time.monotonic()
            entry = [s, opened, None, kind]
            try:
                if first[kind]:
                    s.send(first[kind].encode())
            except OSError:
                entry[2] = opened
            with self.lock:
                self.socks.append(entry)

    def add(self, sock, since, kind="drip"):
        sock.setblocking(False)
        with self.lock:
            self.socks.append([sock, since, None, kind])

    def poll(self):
        """Mark the connections the server has closed."""
        now = time.monotonic()
        with self.lock:
            for e in self.socks:
                if e[2] is None and server_closed(e[0]):
                    e[2] = now

    def drip(self):
        """Every DRIP s a byte to send or 512 to read; every 0.05 s a look for closes."""
        next_drip = 0
        while not self.stop:
            now = time.monotonic()
            if now >= next_drip:
                next_drip = now + DRIP
                self.step(now)
            self.poll()
            time.sleep(0.05)

    def step(self, now):
        with self.lock:
            for e in self.socks:
                if e[2] is not None or e[3] not in ("drip", "trickle"):
                    continue
                try:
                    if e[3] == "drip":
                        e[0].send(b"a")
                    else:
                        e[0].recv(512)
                except BlockingIOError:
                    pass
                except OSError:
                    e[2] = now

    def open_count(self, entries=None):
        self.poll()
        with self.lock:
            return sum(1 for e in (entries or self.socks) if e[2] is None)

    def wait_closed(self, until):
        while time.monotonic() < until and self.open_count():
            time.sleep(0.05)
        return self.open_count()

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
    except (OSError, http.client.HTTPException) as e:
        return "%s" % (e.__class__.__name__,), time.monotonic() - t0


def under_load(kogei, work):
    c = Console(kogei, work + "/L", [], extra=["--header-timeout", str(TIMEOUT)])
    slow = Slow(c)
    try:
        st, dt = timed_get(c, "127.0.0.1")
        check(st == 200, "an unloaded console answers (%s)" % st)
        # 1. 80 slow connections from one address: 16 kept, the stalest closed as others
        # come.
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
        slow.add(ka.sock, t_ka)
        # 3. The deadline: every slow connection closed TIMEOUT s after its start.
        left = slow.wait_closed(max(t_b, t_ka) + TIMEOUT + 3)
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


SEND = 3.0         # --send-timeout (and --header-timeout) of the console with slow readers
BIG = 24 << 20     # the file the readers ask for
OPERATOR = "127.0.0.1"


def keepalive_idlers(slow, c, source, n):
    """Connections that get one answer, read it, then keep the connection idle."""
    for _ in range(n):
        t0 = time.monotonic()
        try:
            conn = http.client.HTTPConnection("127.0.0.1", c.port, timeout=5,
                                              source_address=(source, 0))
            conn.request("GET", "/api/state", headers={"Host": c.hostport})
            conn.getresponse().read()
            slow.add(conn.sock, time.monotonic(), "idle")
        except (OSError, http.client.HTTPException):
            with slow.lock:
                slow.socks.append([socket.socket(), t0, t0, "idle"])


def steady_reader(c, source, path, out):
    """Download path reading 64 KiB every 20 ms (at most 3.2 MB/s): out gets the bytes,
    the seconds and the error, if any."""
    t0 = time.monotonic()
    n = 0
    try:
        conn = http.client.HTTPConnection("127.0.0.1", c.port, timeout=10,
                                          source_address=(source, 0))
        conn.request("GET", path, headers={"Host": c.hostport})
        r = conn.getresponse()
        while True:
            chunk = r.read(65536)
            if not chunk:
                break
            n += len(chunk)
            time.sleep(0.02)
        conn.close()
        out.update(bytes=n, seconds=time.monotonic() - t0, error=None)
    except (OSError, http.client.HTTPException) as e:
        out.update(bytes=n, seconds=time.monotonic() - t0, error=repr(e))


def closing_ages(slow, entries):
    with slow.lock:
        return [e[2] - e[1] for e in entries if e[2] is not None]


def slow_readers(kogei, work):
    """Readers that stop reading, slow senders and idlers, many of them on the
    operator's own address, while a client there is answered."""
    c = Console(kogei, work + "/R", [], extra=["--header-timeout", str(SEND),
                                                "--send-timeout", str(SEND)])
    with open(work + "/R/big.bin", "wb") as f:
        f.truncate(BIG)
    big = "/session/big.bin"
    slow = Slow(c)
    steady = {}
    try:
        # the deadlines, on an address below its cap (nothing there is closed early)
        slow.open("127.0.0.3", 6, "reader", big)
        slow.open("127.0.0.3", 2, "trickle", big)
        slow.open("127.0.0.3", 4, "drip")
        slow.open("127.0.0.3", 4, "idle")
        below_cap = list(slow.socks)
        # the operator's address, crowded
        slow.open(OPERATOR, 32, "reader", big)
        slow.open(OPERATOR, 8, "drip")
        slow.open(OPERATOR, 8, "idle")
        keepalive_idlers(slow, c, OPERATOR, 8)
        reader = threading.Thread(target=steady_reader, args=(c, "127.0.0.4", big, steady))
        reader.start()
        time.sleep(0.5)
        paths = ["/api/state", "/", "/api/session", "/console.css"]
        answered, worst = 0, 0.0
        for i in range(40):
            if i == 20:  # more readers arrive while the client is at work
                slow.open(OPERATOR, 32, "reader", big)
            st, dt = timed_get(c, OPERATOR, paths[i % len(paths)], timeout=3)
            if st == 200 and dt < 3:
                answered += 1
                worst = max(worst, dt)
            time.sleep(0.2)
        hostile = len(slow.socks)
        check(answered >= 38, "with %d hostile sockets (readers of a %d MiB file that never "
              "read, slow senders, idlers), %d of them from %s, a client there gets >= 38 of "
              "40 requests answered within 3 s: %d" % (hostile, BIG >> 20, hostile - len(below_cap),
                                                       OPERATOR, answered))
        print("slow readers: %d hostile sockets; %d of 40 requests answered from %s, the "
              "slowest in %.3f s" % (hostile, answered, OPERATOR, worst))
        left = slow.wait_closed(time.monotonic() + SEND + 2)
        check(left == 0, "every hostile socket is closed by the server (%d of %d left)"
              % (left, hostile))
        for kind in ("reader", "trickle", "drip", "idle"):
            mine = [e for e in below_cap if e[3] == kind]
            ages = closing_ages(slow, mine)
            if check(len(ages) == len(mine), "%s connections below the cap: all closed (%d of "
                     "%d)" % (kind, len(ages), len(mine))):
                check(min(ages) >= SEND - 0.3 and max(ages) <= SEND + 1.5,
                      "%s connections closed %.2f..%.2f s after their start (deadline %.1f s)"
                      % (kind, min(ages), max(ages), SEND))
                print("%s connections closed %.2f..%.2f s after their start (deadline %.1f s)"
                      % (kind, min(ages), max(ages), SEND))
        ages = closing_ages(slow, slow.socks[len(below_cap):])
        check(ages and max(ages) <= SEND + 1.5, "hostile sockets on %s closed within %.1f s of "
              "their start (the longest %.2f s)" % (OPERATOR, SEND + 1.5, max(ages or [-1])))
        reader.join(30)
        check(steady.get("bytes") == BIG and not steady.get("error") and
              steady.get("seconds", 0) > SEND,
              "a reader at 3 MB/s gets all %d bytes although it takes longer than the send "
              "deadline: %r" % (BIG, steady))
        print("a steady reader got %s bytes in %.1f s" % (steady.get("bytes"),
                                                         steady.get("seconds", -1)))
    finally:
        slow.close()
        rc = c.stop()
        check(rc == 0, "the console stops on SIGTERM with 0 (got %s)" % rc)
        with open(c.log) as f:
            log = f.read()
        print("".join(l for l in log.splitlines(True) if "connection" in l or "answer" in l))
        check("cut off at the send deadline" in log,
              "the console reports the answers it cut off: %r" % log[-400:])


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
    for opt in ("--header-timeout", "--send-timeout"):
        for bad in ("0.05", "3601", "x", "nan"):
            r = subprocess.run([kogei, "console", "--session", work + "/U", "--listen",
                                "127.0.0.1:0", opt, bad],
                               capture_output=True, text=True, timeout=20)
            check(r.returncode == 2 and opt in r.stderr,
                  "%s %s: expected exit 2 naming the option (exit %d: %s)"
                  % (opt, bad, r.returncode, r.stderr.strip()[:200]))


def main():
    kogei, parent = sys.argv[1:3]
    work = tempfile.mkdtemp(prefix="console-load-", dir=parent)
    usage(kogei, work)
    under_load(kogei, work)
    slow_readers(kogei, work)
    long_poll(kogei, work)
    print("console-load: %s" % ("FAIL (%d)" % len(failures) if failures else "ok"))
    if not failures:
        shutil.rmtree(work)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
