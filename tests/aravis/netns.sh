#!/bin/sh
# Run a command in a private network namespace whose only interface is loopback, so
# nothing Aravis sends (discovery broadcasts on every interface) can leave this
# machine. Unprivileged: unshare -r maps the caller to root inside a new user
# namespace. Exit 77 (skip) where that is not allowed.
if ! command -v unshare >/dev/null 2>&1 || ! command -v ip >/dev/null 2>&1; then
	echo "SKIP: unshare (util-linux) and ip (iproute2) are needed for a private network namespace"
	exit 77
fi
if ! unshare -rn true 2>/dev/null; then
	echo "SKIP: unshare -rn is not permitted here (unprivileged user namespaces disabled)"
	exit 77
fi
exec unshare -rn sh -c 'ip link set lo up || exit 77; exec "$@"' netns "$@"
