#!/bin/sh
# Sourced by test_iiif.sh: an image server as a museum runs one (docs/iiif.md), on
# 127.0.0.1 only, with its own configuration in $T: iipsrv (Debian iipimage-server) as a
# FastCGI server on a free port, and lighttpd on another in front of it:
#   /iiif/...   -> iipsrv (URI_MAP iiif=>IIIF), images below FILESYSTEM_PREFIX=DIR/
#   /files/...  -> DIR's files (the manifests, the label maps)
#   /osd/...    -> OpenSeadragon's build, when given
# iiif_free_port prints a free TCP port of 127.0.0.1; iiif_start DIR PORT [OSD_DIR]
# starts both in the foreground of their own process groups (setsid) and waits until
# lighttpd answers; iiif_stop stops them by their ids. Needs T and PY set. iipsrv
# encodes its answers at JPEG_QUALITY 95 (its default 75 costs colour: docs/iiif.md);
# IIIF_JPEG_QUALITY overrides it.
IIPSRV=${IIPSRV:-/usr/lib/iipimage-server/iipsrv.fcgi}
LIGHTTPD=${LIGHTTPD:-$(command -v lighttpd || echo /usr/sbin/lighttpd)}
iip_pid=
lt_pid=

iiif_need() {
	[ -x "$IIPSRV" ] || kg_skip "iipsrv is not installed (Debian package iipimage-server)"
	[ -x "$LIGHTTPD" ] || kg_skip "lighttpd is not installed (Debian package lighttpd)"
}

iiif_free_port() {
	"$PY" -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

iiif_start() { # DIR PORT [OSD_DIR]
	fport=$(iiif_free_port)
	osd_alias=
	[ -n "${3:-}" ] && osd_alias=", \"/osd/\" => \"$3/\""
	cat >"$T/lighttpd.conf" <<EOF
server.document-root = "$1"
server.bind = "127.0.0.1"
server.port = $2
server.modules = ("mod_alias", "mod_fastcgi")
server.errorlog = "$T/lighttpd.log"
server.pid-file = "$T/lighttpd.pid"
alias.url = ("/files/" => "$1/"$osd_alias)
mimetype.assign = (".json" => "application/json", ".js" => "text/javascript",
  ".png" => "image/png", ".jpg" => "image/jpeg", ".html" => "text/html",
  ".tif" => "image/tiff")
fastcgi.server = ("/iiif/" => (("host" => "127.0.0.1", "port" => $fport,
  "check-local" => "disable")))
EOF
	set +m
	FILESYSTEM_PREFIX="$1/" URI_MAP="iiif=>IIIF" LOGFILE="$T/iipsrv.log" VERBOSITY=1 \
		MAX_CVT=5000 JPEG_QUALITY=${IIIF_JPEG_QUALITY:-95} setsid "$IIPSRV" --bind "127.0.0.1:$fport" >"$T/iipsrv.out" 2>&1 &
	iip_pid=$!
	setsid "$LIGHTTPD" -D -f "$T/lighttpd.conf" >"$T/lighttpd.out" 2>&1 &
	lt_pid=$!
	i=0
	# up when lighttpd answers anything (a 404 too)
	until "$PY" -c "import urllib.request, urllib.error
try:
    urllib.request.urlopen('http://127.0.0.1:$2/files/', timeout=2)
except urllib.error.HTTPError:
    pass" 2>/dev/null; do
		i=$((i + 1))
		if [ $i -ge 100 ] || ! kill -0 "$lt_pid" 2>/dev/null || ! kill -0 "$iip_pid" 2>/dev/null
		then
			echo "FAIL: the servers did not start; lighttpd said:"
			cat "$T/lighttpd.out" "$T/lighttpd.log" 2>/dev/null
			echo "iipsrv said:"
			cat "$T/iipsrv.out" "$T/iipsrv.log" 2>/dev/null
			return 1
		fi
		sleep 0.1
	done
}

iiif_stop() {
	for p in $lt_pid $iip_pid; do
		kill -TERM "-$p" 2>/dev/null
		i=0
		while kill -0 "$p" 2>/dev/null && [ $i -lt 50 ]; do
			sleep 0.1
			i=$((i + 1))
		done
		kill -KILL "-$p" 2>/dev/null
		wait "$p" 2>/dev/null
	done
	lt_pid=
	iip_pid=
}
