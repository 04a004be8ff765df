"""Shared by the console tests: start `kogei console` on a free loopback port, stop
it by its process id, and speak HTTP to it (the standard library only)."""
import http.client
import json
import os
import re
import signal
import subprocess
import sys
import time

failures = []


def fail(msg):
    failures.append(msg)
    print("FAIL: " + msg, file=sys.stderr)


def check(cond, msg):
    if not cond:
        fail(msg)
    return cond


class Console:
    def __init__(self, kogei, session, cameras, listen="127.0.0.1:0", extra=(), log=None):
        args = [kogei, "console", "--session", session, "--listen", listen]
        for c in cameras:
            args += ["--camera", c]
        args += list(extra)
        self.log = log or session + ".console.log"
        self.out = open(self.log, "w+")
        self.proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=self.out, text=True)
        line = ""
        deadline = time.time() + 20
        while time.time() < deadline:
            line = self.proc.stdout.readline()
            if not line or line.startswith("open "):
                break
        m = re.match(r"open http://(\[[^\]]+\]|[^:/]+):(\d+)/(?:\?token=([0-9a-f]+))?", line)
        if not m:
            err = self.stderr()
            self.stop()
            raise RuntimeError("kogei console did not start: %r; %s" % (line, err))
        self.host, self.port, self.token = m.group(1), int(m.group(2)), m.group(3)
        self.hostport = "%s:%d" % (self.host, self.port)
        self.url = "http://%s/" % self.hostport

    def stderr(self):
        self.out.flush()
        with open(self.log) as f:
            return f.read()

    def stop(self):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.out.close()
        return self.proc.returncode

    def request(self, method, path, body=None, headers=None, token=True, origin=True):
        h = {"Host": self.hostport}
        if token and self.token:
            h["X-Kogei-Token"] = self.token
        if method == "POST" and origin:
            h["Origin"] = "http://" + self.hostport
        if body is not None:
            body = json.dumps(body)
            h["Content-Type"] = "application/json"
        h.update(headers or {})
        host = self.host.strip("[]")
        conn = http.client.HTTPConnection(host, self.port, timeout=30)
        conn.request(method, path, body=body, headers=h)
        r = conn.getresponse()
        data = r.read()
        conn.close()
        return r.status, data

    def json(self, method, path, body=None, **kw):
        status, data = self.request(method, path, body, **kw)
        try:
            return status, json.loads(data)
        except ValueError:
            return status, {"raw": data[:200]}

    def wait_job(self, timeout=60):
        deadline = time.time() + timeout
        while time.time() < deadline:
            _, s = self.json("GET", "/api/state")
            if not s["job"]["running"]:
                return s
            time.sleep(0.2)
        return None
