#!/bin/sh
# A real single-node Slurm (scripts/slurm-cluster.sh through scripts/with-slurm.sh, in a
# private network namespace): a job array with a throttle (--array=0-3%2) on a node
# with 4 CPUs, and a job that depends on it (--dependency=afterany). Checks that every
# task ran and succeeded, that never more than 2 tasks ran at once, that the dependent
# job started after the last task ended, and that the wrapper stopped every daemon and
# passed the command's exit status on. Skips (77) without the Slurm and munge packages
# or where a network namespace cannot be made (not root).
#
#   test_slurm_cluster.sh SOURCE_ROOT
. "$(dirname "$0")/../lib.sh"

if [ -z "${KOGEI_SLURM_DIR:-}" ]; then
	# Outside: run this script again inside the wrapper, keeping its folder to check
	# afterwards that no daemon it started still runs.
	root=${1:-$KG_ROOT}
	kg_temp
	KEEP=1 KOGEI_SLURM_CPUS=4 TMPDIR=/tmp KG_SLURM_REPORT=$T/inner \
		"$root/scripts/with-slurm.sh" /bin/sh "$0" "$root" 2>"$T/wrapper.err"
	rc=$?
	cat "$T/wrapper.err" >&2
	[ "$rc" = 77 ] && exit 77
	if [ "$rc" != 0 ]; then
		echo "FAIL: the test inside the cluster exited $rc"
		fail=1
	fi
	kept=$(sed -n 's/^with-slurm: kept //p' "$T/wrapper.err")
	check_eval "the wrapper passes the command's status on (it exited $rc)" \
		'[ -f "$T/inner" ] && [ "$rc" = "$(cat "$T/inner")" ]'
	if [ -n "$kept" ] && [ -d "$kept" ]; then
		for pid in $(cat "$T/inner.pids" 2>/dev/null); do
			check_eval "daemon $pid stopped by the wrapper" \
				'! grep -qs "^[^)]*) [^Z]" /proc/$pid/stat'
		done
		check "the wrapper named its daemons (inner.pids)" [ -s "$T/inner.pids" ]
		check "PID files removed by stop" [ -z "$(ls "$kept/run/"*.pid 2>/dev/null)" ]
		rm -rf "$kept"
	else
		echo "FAIL: the wrapper did not name the folder it kept"
		fail=1
	fi
	exit $fail
fi

# Inside the wrapper: SLURM_CONF and KOGEI_SLURM_DIR are set.
kg_temp
trap 'echo $? >"$KG_SLURM_REPORT"; [ -n "${KEEP_INNER:-}" ] || rm -rf "$T"' EXIT
cat "$KOGEI_SLURM_DIR"/run/munged.pid "$KOGEI_SLURM_DIR"/run/slurmctld.pid \
	"$KOGEI_SLURM_DIR"/run/slurmd.pid >"$KG_SLURM_REPORT.pids"

cpus=$(sinfo -h -N -o %c)
check "the node has the 4 CPUs asked for (got '$cpus')" [ "$cpus" = 4 ]

# Each task: its start and end time (ns) in out/task_N; 2 s of work in between.
mkdir -p "$T/out"
array=$(sbatch --parsable --array=0-3%2 -o "$T/out/slurm_%A_%a.log" --chdir "$T" \
	--wrap 'echo "$(date +%s%N) start" >out/task_$SLURM_ARRAY_TASK_ID; sleep 2; echo "$(date +%s%N) end" >>out/task_$SLURM_ARRAY_TASK_ID') || {
	echo "FAIL: sbatch of the array refused"
	exit 1
}
dep=$(sbatch --parsable --dependency=afterany:"$array" -o "$T/out/slurm_%j.log" --chdir "$T" \
	--wrap 'echo "$(date +%s%N) start" >out/dependent') || {
	echo "FAIL: sbatch of the dependent job refused"
	exit 1
}

# Wait (bounded: 45 s, polled every 0.5 s) until neither is queued or running.
i=0
while [ $i -lt 90 ]; do
	left=$(squeue -h -j "$array,$dep" -o %i 2>/dev/null | wc -l)
	[ "$left" = 0 ] && break
	sleep 0.5
	i=$((i + 1))
done
check "array $array and job $dep finished within 45 s" [ "$left" = 0 ]

for t in 0 1 2 3; do
	info=$(scontrol -o show job "${array}_$t" 2>/dev/null)
	check "task $t completed ($(echo "$info" | grep -o 'JobState=[A-Z]*'))" \
		[ -n "$(echo "$info" | grep 'JobState=COMPLETED' | grep 'ExitCode=0:0')" ]
	check "task $t wrote start and end" [ "$(grep -c -E '^[0-9]+ (start|end)$' "$T/out/task_$t" 2>/dev/null)" = 2 ]
done
info=$(scontrol -o show job "$dep" 2>/dev/null)
check "dependent job completed ($(echo "$info" | grep -o 'JobState=[A-Z]*'))" \
	[ -n "$(echo "$info" | grep 'JobState=COMPLETED')" ]
check "dependent job ran" [ -s "$T/out/dependent" ]

# The intervals: at most 2 tasks at any task's start (the throttle; the node would
# take 4), and the dependent job after the last end.
cat "$T"/out/task_* >"$T/times" 2>/dev/null
awk -v dep="$(cut -d' ' -f1 "$T/out/dependent" 2>/dev/null)" '
	$2 == "start" { s[NR] = $1 } $2 == "end" { e[NR - 1] = $1; if ($1 > last) last = $1 }
	END {
		most = 0
		for (i in s) {
			n = 0
			for (j in s) if (s[j] <= s[i] && e[j] > s[i]) n++
			if (n > most) most = n
		}
		print "most at once: " most "; dependent started " (dep - last) / 1e9 " s after the last task ended"
		if (most < 1 || most > 2) { print "FAIL: the throttle %2 let " most " tasks run at once"; bad = 1 }
		if (dep == "" || dep < last) { print "FAIL: the dependent job started before the array ended"; bad = 1 }
		exit bad
	}' "$T/times" || fail=1
exit $fail
