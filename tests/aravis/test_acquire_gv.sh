#!/bin/sh
# End to end over GigE Vision on loopback (run inside netns.sh): `kogei acquire` records
# a chart capture from arv-fake-gv-camera-0.8 opened as aravis:127.0.0.1 (Mono16, a
# region), `kogei acquire --camera replay:` reproduces its mean and variance images and
# every raw frame bit for bit; once the camera is gone, acquire exits 3 naming it and
# leaves the session as it was.
# usage: test_acquire_gv.sh KOGEI
set -u
kogei=$1
command -v arv-fake-gv-camera-0.8 >/dev/null 2>&1 ||
	{ echo "SKIP: arv-fake-gv-camera-0.8 (aravis-tools) is not installed"; exit 77; }
tmp=$(mktemp -d)
server=
cleanup() {
	[ -n "$server" ] && kill "$server" 2>/dev/null && wait "$server" 2>/dev/null
	rm -rf "$tmp"
}
trap cleanup EXIT
fail() { echo "FAIL: $*"; exit 1; }

arv-fake-gv-camera-0.8 -i 127.0.0.1 >"$tmp/server.log" 2>&1 &
server=$!
# Wait for its GVCP port (3956 = 0x0F74) to be bound in this namespace.
i=0
while ! grep -q ':0F74 ' /proc/net/udp; do
	i=$((i + 1))
	[ $i -gt 50 ] && fail "the fake camera did not bind UDP port 3956"
	sleep 0.1
done

S=$tmp/S
"$kogei" acquire --camera aravis:127.0.0.1 --out "$S" --kind chart --frames 4 \
	--format mono16 --roi 320x240+16+8 >"$tmp/acq.log" 2>&1 ||
	{ cat "$tmp/acq.log"; fail "kogei acquire from aravis:127.0.0.1 failed"; }
grep -q '"transport": "GigE Vision"' "$S/session.json" || fail "session.json: no GigE Vision camera"
grep -q 'mono16 16 bits 320x240+16+8' "$tmp/acq.log" || { cat "$tmp/acq.log"; fail "format or region not applied"; }
# GigE Vision's packet counters reach the operator and the manifest.
grep -q 'stream: 4 completed, 0 dropped, 0 incomplete, 0 failed, 0 timeouts, [0-9]* packets resent, 0 packets missing' "$tmp/acq.log" ||
	{ cat "$tmp/acq.log"; fail "the stream line lacks the packet counts"; }
grep -q '"missing_packets": 0' "$S/session.json" || fail "session.json: no missing_packets count"
n=$(ls "$S/frames/chart-0001" | grep -c '\.raw$')
[ "$n" = 4 ] || fail "$n raw frames recorded, expected 4"
f1=$(sha256sum <"$S/frames/chart-0001/000001.raw")
f2=$(sha256sum <"$S/frames/chart-0001/000002.raw")
[ "$f1" != "$f2" ] || fail "frames 1 and 2 are identical: the fake's pattern should move"
[ "$(wc -c <"$S/frames/chart-0001/000001.raw")" = $((320 * 240 * 2)) ] || fail "frame size"

# The camera goes away: a clear device error, exit 3, and the session untouched.
kill "$server"; wait "$server" 2>/dev/null; server=
before=$(cat "$S/session.json" "$S/frames/index.jsonl" | sha256sum)
"$kogei" acquire --camera aravis:127.0.0.1 --out "$S" --kind chart --frames 4 \
	>"$tmp/gone.log" 2>&1
rc=$?
[ $rc = 3 ] || { cat "$tmp/gone.log"; fail "acquire without a camera exited $rc, expected 3"; }
grep -q "aravis:127.0.0.1.*no GigE Vision camera answers" "$tmp/gone.log" ||
	{ cat "$tmp/gone.log"; fail "the error should name the camera"; }
after=$(cat "$S/session.json" "$S/frames/index.jsonl" | sha256sum)
[ "$before" = "$after" ] || fail "a failed acquire changed the session"

R=$tmp/R
"$kogei" acquire --camera "replay:$S" --out "$R" --kind chart --frames 4 >"$tmp/replay.log" 2>&1 ||
	{ cat "$tmp/replay.log"; fail "kogei acquire from replay:$S failed"; }
for f in captures/chart-0001/mean.tif captures/chart-0001/variance.tif \
	frames/chart-0001/000001.raw frames/chart-0001/000002.raw \
	frames/chart-0001/000003.raw frames/chart-0001/000004.raw; do
	cmp -s "$S/$f" "$R/$f" || fail "$f differs between the recording and its replay"
done
echo "acquire-gv: ok"
