#!/bin/sh
# Run a command against a private single-node Slurm cluster that lives only as long as
# the command:
#
#   scripts/with-slurm.sh COMMAND [ARGS...]
#
# In a new network namespace (unshare -n: as root, no user namespace, because
# slurmstepd calls setgroups, which a user namespace denies) whose only device is
# loopback, it starts the cluster of scripts/slurm-cluster.sh in a temporary folder,
# exports what sbatch, squeue and scontrol need (SLURM_CONF; KOGEI_SLURM_DIR names the
# folder, its log/ has the daemons' logs), runs COMMAND, stops the daemons it started
# (by their PIDs, also when COMMAND fails or the wrapper is interrupted) and exits with
# COMMAND's status. Nothing it sends can leave the machine.
#
# Exit 77 (a skipped test) with a message when the Slurm or munge packages are missing
# or a network namespace cannot be made; 3 when the cluster does not start. KEEP=1
# keeps the temporary folder (its path is printed on stderr).
set -eu

here=$(cd "$(dirname "$0")" && pwd)

if [ $# -lt 1 ]; then
	echo "usage: with-slurm.sh COMMAND [ARGS...]" >&2
	exit 2
fi

if [ "${KOGEI_WITH_SLURM_NETNS:-}" != "$$" ]; then
	for c in munged mungekey slurmctld slurmd sbatch squeue scontrol sinfo; do
		if ! command -v "$c" >/dev/null 2>&1; then
			echo "SKIP: $c not found: a test Slurm needs the Debian packages slurmctld slurmd slurm-client munge (scripts/setup.sh installs them)"
			exit 77
		fi
	done
	if ! command -v unshare >/dev/null 2>&1 || ! command -v ip >/dev/null 2>&1; then
		echo "SKIP: unshare (util-linux) and ip (iproute2) are needed for a private network namespace"
		exit 77
	fi
	if [ "$(id -u)" != 0 ] || ! unshare -n true 2>/dev/null; then
		echo "SKIP: a network namespace for the test Slurm needs root (unshare -n; slurmd starts jobs as root)"
		exit 77
	fi
	# exec keeps this PID, so a signal to the wrapper reaches the shell below.
	KOGEI_WITH_SLURM_NETNS=$$ exec unshare -n -- /bin/sh "$0" "$@"
fi
unset KOGEI_WITH_SLURM_NETNS

# Inside the namespace. glibc resolves nothing while 127.0.0.1 is the only IPv4
# address (AI_ADDRCONFIG): a documentation-only address (RFC 5737) beside it.
if ! ip link set lo up || ! ip addr add 192.0.2.1/32 dev lo; then
	echo "SKIP: cannot set up loopback in the network namespace"
	exit 77
fi

# The munge socket's path must fit a Unix socket address (108 bytes): /tmp unless
# TMPDIR is short.
base=${TMPDIR:-/tmp}
[ ${#base} -le 60 ] || base=/tmp
dir=$(mktemp -d "$base/kogei-slurm.XXXXXX")
child=

cleanup() {
	"$here/slurm-cluster.sh" stop "$dir" || true
	if [ -n "${KEEP:-}" ]; then
		echo "with-slurm: kept $dir" >&2
	else
		rm -rf "$dir"
	fi
}
trap cleanup EXIT
on_signal() {
	trap '' INT TERM HUP
	if [ -n "$child" ]; then
		kill -TERM "-$child" 2>/dev/null || kill -TERM "$child" 2>/dev/null || true
		wait "$child" 2>/dev/null || true
	fi
	exit "$1"
}
trap 'on_signal 130' INT
trap 'on_signal 143' TERM
trap 'on_signal 129' HUP

if ! "$here/slurm-cluster.sh" start "$dir" 2>"$dir.start"; then
	cat "$dir.start" >&2
	rm -f "$dir.start"
	echo "with-slurm: the test Slurm did not start" >&2
	exit 3
fi
rm -f "$dir.start"
eval "$("$here/slurm-cluster.sh" env "$dir")"
KOGEI_SLURM_DIR=$dir
export KOGEI_SLURM_DIR

# In the background and waited for, so a signal is handled at once: the traps above
# stop the command's whole process group (setsid, which execs: its PID is the
# group's), then the cluster. stdin stays the wrapper's.
rc=0
exec 3<&0
setsid "$@" <&3 3<&- &
child=$!
wait "$child" || rc=$?
child=
exit "$rc"
