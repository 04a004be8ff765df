#!/bin/sh
# A private single-node Slurm cluster (Debian 12's Slurm 22.05 and munge) whose
# configuration, state, spool, logs, munge key and socket all live in one folder.
#
#   scripts/slurm-cluster.sh start DIR   create DIR if needed, write its configuration
#                                        and start munged, slurmctld and slurmd
#   scripts/slurm-cluster.sh env DIR     print the shell lines that point sbatch, squeue,
#                                        scontrol and sinfo at it:  eval "$(... env DIR)"
#   scripts/slurm-cluster.sh stop DIR    stop the daemons that `start DIR` started
#   scripts/slurm-cluster.sh status DIR  print which of them run (exit 1 when none)
#
# It never reads or writes the system's Slurm or munge configuration (/etc/slurm,
# /etc/munge, /run/munge): every daemon gets its paths on its command line or from
# DIR/slurm.conf. Every address is loopback: the controller and the node listen on
# 127.0.0.1 (KOGEI_SLURM_ADDR to change) at ports 6817 and 6818 (KOGEI_SLURM_PORT for the
# controller's; the node's is the next one up). The daemons run as root (slurmd starts
# each job as the user who submitted it); one node named kogei1 with the machine's cores
# (KOGEI_SLURM_CPUS to change) in one partition named kogei.
#
# On a machine whose only IPv4 address is 127.0.0.1 (a fresh network namespace), glibc
# refuses to resolve even "127.0.0.1" and slurmctld stops after 10 s: give the loopback
# device a second, documentation-only address first (ip addr add 192.0.2.1/32 dev lo).
# scripts/with-slurm.sh does that in a private network namespace for the tests.
set -eu

usage() {
	echo "usage: slurm-cluster.sh start|stop|env|status DIR" >&2
	exit 2
}

[ $# -eq 2 ] || usage
cmd=$1
case "$2" in
/*) dir=$2 ;;
*) dir=$(pwd)/$2 ;;
esac

addr=${KOGEI_SLURM_ADDR:-127.0.0.1}
port=${KOGEI_SLURM_PORT:-6817}
case "$port" in
'' | *[!0-9]*)
	echo "slurm-cluster: KOGEI_SLURM_PORT: expected a port number, got '$port'" >&2
	exit 2
	;;
esac
node_port=$((port + 1))

# The PID a daemon's PID file in DIR names, only when that process is still the daemon
# this folder started (its command line names DIR): a PID reused by another process is
# never signalled.
daemon_pid() {
	pidfile=$dir/run/$1.pid
	[ -f "$pidfile" ] || return 1
	pid=$(cat "$pidfile")
	case "$pid" in
	'' | *[!0-9]*) return 1 ;;
	esac
	alive "$pid" || return 1
	tr '\0' ' ' <"/proc/$pid/cmdline" | grep -qF "$dir/" || return 1
	echo "$pid"
}

# Whether process $1 runs (a zombie, which its parent has not reaped yet, does not).
alive() {
	[ -r "/proc/$1/stat" ] || return 1
	state=$(sed 's/.*) //' "/proc/$1/stat" 2>/dev/null | cut -c1)
	[ -n "$state" ] && [ "$state" != Z ]
}

print_env() {
	echo "SLURM_CONF=$dir/slurm.conf; export SLURM_CONF"
	# sbatch and friends take the controller and the munge socket from SLURM_CONF;
	# these only keep a user's own defaults (a partition, an account) out of the way.
	echo "unset SBATCH_PARTITION SBATCH_ACCOUNT SQUEUE_FORMAT SQUEUE_FORMAT2"
}

stop_daemons() {
	# All three at once: each takes one to two seconds to notice and finish.
	pids=
	for d in slurmd slurmctld munged; do
		if pid=$(daemon_pid "$d"); then
			kill -TERM "$pid" 2>/dev/null || true
			pids="$pids $d:$pid"
		fi
	done
	i=0
	for dp in $pids; do
		d=${dp%%:*}
		pid=${dp#*:}
		while alive "$pid" && [ $i -lt 100 ]; do
			sleep 0.1
			i=$((i + 1))
		done
		if alive "$pid"; then
			echo "slurm-cluster: $d ($pid) did not stop in 10 s: killing it" >&2
			kill -KILL "$pid" 2>/dev/null || true
		fi
	done
	for d in slurmd slurmctld munged; do
		rm -f "$dir/run/$d.pid"
	done
}

write_config() {
	cpus=${KOGEI_SLURM_CPUS:-$(nproc)}
	user=$(id -un)
	# slurmctld runs only on the host SlurmctldHost names: this machine's short name.
	host=$(hostname -s)
	: >"$dir/plugstack.conf"
	cat >"$dir/slurm.conf.tmp" <<EOF
# A private single-node cluster written by scripts/slurm-cluster.sh: every path is
# under $dir, every address is $addr.
ClusterName=kogei
SlurmctldHost=$host($addr)
SlurmctldPort=$port
SlurmdPort=$node_port
SlurmUser=$user
SlurmdUser=$user
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$dir/munge/munge.socket
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool/%n
SlurmctldPidFile=$dir/run/slurmctld.daemon.pid
SlurmdPidFile=$dir/run/slurmd.daemon.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
PlugStackConfig=$dir/plugstack.conf
# No systemd, no cgroups, no accounting database.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SwitchType=switch/none
MpiDefault=none
LaunchParameters=use_interactive_step
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
SlurmdParameters=config_overrides
# Finished jobs stay visible to scontrol for 10 minutes.
MinJobAge=600
SlurmctldTimeout=30
SlurmdTimeout=30
InactiveLimit=0
KillWait=5
NodeName=kogei1 NodeHostname=kogei1 NodeAddr=$addr CPUs=$cpus State=UNKNOWN
PartitionName=kogei Nodes=kogei1 Default=YES MaxTime=INFINITE State=UP
EOF
	mv "$dir/slurm.conf.tmp" "$dir/slurm.conf"
}

# Wait up to $1 tenths of a second for the controller to answer and the node to be up.
wait_ready() {
	i=0
	while [ $i -lt "$1" ]; do
		for d in munged slurmctld slurmd; do
			if ! daemon_pid "$d" >/dev/null; then
				echo "slurm-cluster: $d stopped while starting; its log:" >&2
				tail -n 20 "$dir/log/$d.log" >&2 2>/dev/null || true
				return 1
			fi
		done
		state=$(SLURM_CONF=$dir/slurm.conf sinfo -h -n kogei1 -o %T 2>/dev/null || true)
		case "$state" in
		idle* | mixed* | allocated*) return 0 ;;
		esac
		sleep 0.1
		i=$((i + 1))
	done
	echo "slurm-cluster: the node is not up after $(($1 / 10)) s (state '$state'); see $dir/log" >&2
	return 1
}

start() {
	for c in munged mungekey slurmctld slurmd sbatch sinfo; do
		if ! command -v "$c" >/dev/null 2>&1; then
			echo "slurm-cluster: $c not found: install slurmctld slurmd slurm-client munge (scripts/setup.sh)" >&2
			exit 3
		fi
	done
	if [ "$(id -u)" != 0 ]; then
		echo "slurm-cluster: slurmd must run as root to start jobs (run as root or with sudo)" >&2
		exit 3
	fi
	for d in munged slurmctld slurmd; do
		if pid=$(daemon_pid "$d"); then
			echo "slurm-cluster: $d already runs for $dir (pid $pid): stop it first" >&2
			exit 3
		fi
	done
	mkdir -p "$dir" "$dir/state" "$dir/spool" "$dir/log" "$dir/run" "$dir/munge"
	# munged refuses a socket folder others can write to; --force below accepts a
	# folder only root can enter.
	chmod 700 "$dir/munge"
	if [ ! -f "$dir/munge/munge.key" ]; then
		mungekey -c -k "$dir/munge/munge.key"
	fi
	chmod 600 "$dir/munge/munge.key"
	write_config

	# Every daemon in the foreground, started from here: its PID is the one in run/.
	# Each in a session of its own (setsid, which execs: the same PID), so a Ctrl-C in
	# the shell that started them does not reach them.
	setsid munged -F --force --key-file="$dir/munge/munge.key" \
		--socket="$dir/munge/munge.socket" --pid-file="$dir/run/munged.daemon.pid" \
		--log-file="$dir/log/munged.log" --seed-file="$dir/munge/munged.seed" \
		</dev/null >>"$dir/log/munged.log" 2>&1 &
	echo $! >"$dir/run/munged.pid"
	i=0
	while [ ! -S "$dir/munge/munge.socket" ] && [ $i -lt 50 ]; do
		sleep 0.1
		i=$((i + 1))
	done
	if [ ! -S "$dir/munge/munge.socket" ]; then
		echo "slurm-cluster: munged did not start; its log:" >&2
		tail -n 20 "$dir/log/munged.log" >&2 || true
		stop_daemons
		exit 3
	fi

	SLURM_CONF=$dir/slurm.conf setsid slurmctld -D -f "$dir/slurm.conf" \
		</dev/null >>"$dir/log/slurmctld.out" 2>&1 &
	echo $! >"$dir/run/slurmctld.pid"
	SLURM_CONF=$dir/slurm.conf setsid slurmd -D -f "$dir/slurm.conf" -N kogei1 \
		</dev/null >>"$dir/log/slurmd.out" 2>&1 &
	echo $! >"$dir/run/slurmd.pid"

	if ! wait_ready 300; then
		stop_daemons
		exit 3
	fi
	echo "slurm-cluster: running in $dir (controller $addr:$port); to use it:" >&2
	echo "  eval \"\$($0 env $dir)\"" >&2
}

case "$cmd" in
start) start ;;
stop) stop_daemons ;;
env) print_env ;;
status)
	any=1
	for d in munged slurmctld slurmd; do
		if pid=$(daemon_pid "$d"); then
			echo "$d: running (pid $pid)"
			any=0
		else
			echo "$d: stopped"
		fi
	done
	exit $any
	;;
*) usage ;;
esac
