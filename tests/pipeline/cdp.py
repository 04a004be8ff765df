"""The Chrome DevTools Protocol over a WebSocket, as the browser tests drive headless
Chromium (report_browser.py, collection_browser.py, iiif_browser.py). Importing it
without python3-websocket skips the test (exit 77)."""
import json
import sys
import time

try:
    import websocket
except ImportError:
    print("SKIP: python3-websocket is not installed")
    sys.exit(77)


class Cdp:
    def __init__(self, url):
        self.ws = websocket.create_connection(url, timeout=30, suppress_origin=True)
        self.next_id = 0
        self.events = []

    def call(self, method, params=None, session=None, timeout=30):
        self.next_id += 1
        msg = {"id": self.next_id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        self.ws.send(json.dumps(msg))
        self.ws.settimeout(timeout)
        deadline = time.time() + timeout
        while time.time() < deadline:
            reply = json.loads(self.ws.recv())
            if reply.get("id") == self.next_id:
                if "error" in reply:
                    raise RuntimeError("%s: %s" % (method, reply["error"]))
                return reply.get("result", {})
            if "method" in reply:
                self.events.append(reply)
        raise RuntimeError("%s: no reply in %d s" % (method, timeout))

    def wait_event(self, name, timeout=30):
        for e in self.events:
            if e["method"] == name:
                return e
        deadline = time.time() + timeout
        while time.time() < deadline:
            self.ws.settimeout(max(0.1, deadline - time.time()))
            try:
                e = json.loads(self.ws.recv())
            except websocket.WebSocketTimeoutException:
                break
            if "method" in e:
                self.events.append(e)
                if e["method"] == name:
                    return e
        return None

    def drain(self, seconds):
        self.wait_event("kogei.never", seconds)
