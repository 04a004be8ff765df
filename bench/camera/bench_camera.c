/* kogei-bench-camera: sustained frame rate and lost frames of the Aravis backend
 * against Aravis' fake GigE Vision camera, beside Aravis' own arv-camera-test-0.8 on
 * the same camera in the same run, and the throughput of recording frames to disk
 * (kg_camera_record_*). A program that measures, not a test.
 *
 * Everything runs in a private network namespace whose only interface is loopback
 * (the program re-executes itself under `unshare -rn`), so no packet can leave the
 * machine. The fake camera (arv-fake-gv-camera-0.8 -i 127.0.0.1) is a child process;
 * both receivers open it by address. Output: a Markdown report on stdout, and in the
 * file named by -o. */
#include <errno.h>
#include <fcntl.h>
#include <ftw.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/statfs.h>
#include <sys/utsname.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "kg_camera.h"
#include "kg_core.h"

extern char **environ;

#define NETNS_ENV "KOGEI_BENCH_CAMERA_NETNS"
#define ADDRESS "127.0.0.1"
#define MAX_SIZES 4

static const char usage[] =
	"usage: kogei-bench-camera [--duration S] [--rate FPS] [--buffers N] [--sizes WxH,...]\n"
	"                          [--record-dir DIR] [-o REPORT.md]\n"
	"\n"
	"Sustained frame rate and lost frames of kogei's Aravis backend against Aravis' fake\n"
	"GigE Vision camera (arv-fake-gv-camera-0.8 on 127.0.0.1), beside arv-camera-test-0.8\n"
	"on the same camera at the same settings (Mono16, the same size and frame rate, packet\n"
	"resend on, automatic socket buffer), then recording throughput to disk through\n"
	"kg_camera_record_* into a temporary session. Runs in a private network namespace\n"
	"(re-executes itself under `unshare -rn`): nothing is sent beyond loopback.\n"
	"\n"
	"  --duration S      seconds per measurement (default 5)\n"
	"  --rate FPS        frame rate asked of the camera (default 1000, the fake's maximum)\n"
	"  --buffers N       kogei's stream buffers (default 8)\n"
	"  --sizes WxH,...   frame sizes (default 640x480,2048x2048)\n"
	"  --record-dir DIR  where the temporary session goes (default $TMPDIR or /tmp)\n"
	"  -o FILE           also write the report to FILE (e.g. docs/bench/camera.md)\n"
	"\n"
	"Exit status: 0 measured, 2 bad usage, 3 the fake camera or a tool could not run.\n";

typedef struct opts {
	double duration, rate;
	int buffers;
	int nsizes, w[MAX_SIZES], h[MAX_SIZES];
	const char *record_dir, *out;
	char command[1024];
} opts;

typedef struct stream_result {
	int ok;
	char note[256];
	double fps, mib_s;
	unsigned long long completed, failed, incomplete, dropped, missing_packets, resent;
} stream_result;


static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ---- the namespace and the fake camera ---------------------------------------- */

static int reexec_in_netns(int argc, char **argv)
{
	char self[4096];
	ssize_t n = readlink("/proc/self/exe", self, sizeof(self) - 1);
	if (n <= 0) {
		fprintf(stderr, "kogei-bench-camera: cannot find its own executable: %s\n",
		        strerror(errno));
		return 3;
	}
	self[n] = 0;
	setenv(NETNS_ENV, "1", 1);
	char **args = calloc((size_t)argc + 8, sizeof(*args));
	if (!args)
		return 3;
	int k = 0;
	args[k++] = "unshare";
	args[k++] = "-rn";
	args[k++] = "sh";
	args[k++] = "-c";
	args[k++] = "ip link set lo up && exec \"$0\" \"$@\"";
	args[k++] = self;
	for (int i = 1; i < argc; i++)
		args[k++] = argv[i];
	execvp("unshare", args);
	fprintf(stderr,
	        "kogei-bench-camera: cannot run `unshare -rn` (%s); the bench needs a private "
	        "network namespace so that Aravis cannot broadcast\n",
	        strerror(errno));
	free(args);
	return 3;
}

static pid_t spawn_quiet(char *const argv[], int stdout_fd)
{
	posix_spawn_file_actions_t fa;
	posix_spawn_file_actions_init(&fa);
	posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
	if (stdout_fd >= 0)
		posix_spawn_file_actions_adddup2(&fa, stdout_fd, 1);
	else
		posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
	posix_spawn_file_actions_addopen(&fa, 2, "/dev/null", O_WRONLY, 0);
	pid_t pid = -1;
	if (posix_spawnp(&pid, argv[0], &fa, NULL, argv, environ) != 0)
		pid = -1;
	posix_spawn_file_actions_destroy(&fa);
	return pid;
}

static void stop_child(pid_t pid)
{
	if (pid <= 0)
		return;
	kill(pid, SIGTERM);
	for (int i = 0; i < 50; i++) {
		if (waitpid(pid, NULL, WNOHANG) == pid)
			return;
		usleep(100000);
	}
	kill(pid, SIGKILL);
	waitpid(pid, NULL, 0);
}

/* Open the fake camera, waiting for it to come up. */
static int open_camera(kg_camera **c, kg_err *err)
{
	int ret = KG_ENODEV;
	double t0 = now_s();
	while (now_s() - t0 < 15 && (ret = kg_camera_open("aravis:" ADDRESS, c, err)))
		usleep(200000);
	return ret;
}

/* ---- kogei's receiver ----------------------------------------------------------- */

static int setup(kg_camera *c, const opts *o, int w, int h, kg_err *err)
{
	kg_frame_format want = {.pixfmt = KG_PIX_MONO16, .bits = 16, .width = w, .height = h};
	int ret = kg_camera_set_format(c, &want, NULL, err);
	if (!ret)
		ret = kg_camera_set(c, KG_FEAT_FRAME_RATE, o->rate, NULL, err);
	return ret;
}

/* Pop and push frames for o->duration seconds after the first frame; record into
 * session when it is not NULL. */
static int run_stream(const opts *o, int w, int h, const char *session, stream_result *sr,
                      kg_err *err)
{
	kg_camera *c = NULL;
	int ret = open_camera(&c, err);
	if (!ret)
		ret = setup(c, o, w, h, err);
	if (!ret)
		ret = kg_camera_start(c, o->buffers, err);
	if (!ret && session)
		ret = kg_camera_record_start(c, session, err);
	kg_frame f;
	if (!ret && !(ret = kg_camera_pop(c, 5000, &f, err)))
		ret = kg_camera_push(c, &f, err);
	unsigned long long frames = 0, bytes = 0;
	double t0 = now_s(), t = t0;
	while (!ret && (t = now_s()) - t0 < o->duration) {
		if ((ret = kg_camera_pop(c, 2000, &f, err)))
			break;
		if (f.status == KG_FRAME_OK) {
			frames++;
			bytes += f.size;
		}
		ret = kg_camera_push(c, &f, err);
	}
	double elapsed = t - t0;
	kg_stream_stats st;
	memset(&st, 0, sizeof(st));
	if (c)
		kg_camera_stats(c, &st);
	if (c && session) {
		kg_err e2 = {{0}};
		int r2 = kg_camera_record_stop(c, &e2);
		if (!ret && r2) {
			ret = r2;
			*err = e2;
		}
	}
	kg_camera_free(&c);
	if (ret)
		return ret;
	sr->ok = 1;
	sr->fps = elapsed > 0 ? (double)frames / elapsed : 0;
	sr->mib_s = elapsed > 0 ? (double)bytes / elapsed / (1024.0 * 1024.0) : 0;
	sr->completed = st.completed;
	sr->failed = st.failed;
	sr->incomplete = st.incomplete;
	sr->dropped = st.dropped;
	sr->missing_packets = st.missing_packets;
	sr->resent = st.resent;
	return 0;
}

/* ---- arv-camera-test-0.8 ------------------------------------------------------ */

static unsigned long long counter(const char *out, const char *name)
{
	const char *p = strstr(out, name);
	unsigned long long v = 0;
	if (p && (p = strchr(p, '=')))
		sscanf(p + 1, "%llu", &v);
	return v;
}

/* The mean of its "N frames/s" lines, the first (start-up) second left out. */
static int run_arv_camera_test(const opts *o, int w, int h, stream_result *r)
{
	char wb[16], hb[16], fb[32], db[32];
	snprintf(wb, sizeof(wb), "%d", w);
	snprintf(hb, sizeof(hb), "%d", h);
	snprintf(fb, sizeof(fb), "%g", o->rate);
	snprintf(db, sizeof(db), "%d", (int)(o->duration + 1.5));
	char *argv[] = {"arv-camera-test-0.8", "-n", ADDRESS, "-w", wb, "-h", hb, "-f", fb,
	                "--features", "PixelFormat=Mono16", "-a", "--duration", db, NULL};
	int fds[2];
	if (pipe(fds) != 0)
		return -1;
	pid_t pid = spawn_quiet(argv, fds[1]);
	close(fds[1]);
	if (pid < 0) {
		close(fds[0]);
		snprintf(r->note, sizeof(r->note), "arv-camera-test-0.8 not found (aravis-tools-cli)");
		return -1;
	}
	size_t cap = 1 << 16, len = 0;
	char *out = malloc(cap);
	ssize_t n;
	while (out && (n = read(fds[0], out + len, cap - len - 1)) > 0) {
		len += (size_t)n;
		if (cap - len < 1024) {
			char *bigger = realloc(out, cap * 2);
			if (!bigger)
				break;
			out = bigger;
			cap *= 2;
		}
	}
	close(fds[0]);
	int status = 0;
	waitpid(pid, &status, 0);
	if (!out)
		return -1;
	out[len] = 0;
	double sum = 0, sum_mib = 0;
	int lines = 0, seen = 0;
	for (char *line = out; line && *line;) {
		char *nl = strchr(line, '\n');
		double fps, mib;
		if (sscanf(line, "%lf frames/s - %lf MiB/s", &fps, &mib) == 2 && seen++ > 0) {
			sum += fps;
			sum_mib += mib;
			lines++;
		}
		line = nl ? nl + 1 : NULL;
	}
	r->completed = counter(out, "n_completed_buffers");
	r->failed = counter(out, "n_failures");
	r->dropped = counter(out, "n_underruns") + counter(out, "n_missing_frames");
	r->missing_packets = counter(out, "n_missing_packets");
	r->resent = counter(out, "n_resent_packets");
	free(out);
	if (!lines) {
		snprintf(r->note, sizeof(r->note), "arv-camera-test-0.8 printed no rate (exit %d)",
		         WIFEXITED(status) ? WEXITSTATUS(status) : -1);
		return -1;
	}
	r->ok = 1;
	r->fps = sum / lines;
	r->mib_s = sum_mib / lines;
	return 0;
}

/* ---- report ------------------------------------------------------------------- */

static void describe_machine(char *buf, size_t len)
{
	char model[160] = "unknown CPU";
	FILE *fp = fopen("/proc/cpuinfo", "r");
	if (fp) {
		char line[512];
		while (fgets(line, sizeof(line), fp))
			if (!strncmp(line, "model name", 10)) {
				const char *v = strchr(line, ':');
				if (v) {
					snprintf(model, sizeof(model), "%s", v + 1 + (v[1] == ' '));
					model[strcspn(model, "\n")] = 0;
				}
				break;
			}
		fclose(fp);
	}
	struct utsname u;
	snprintf(buf, len, "%s, %ld online CPUs, %s", model, sysconf(_SC_NPROCESSORS_ONLN),
	         uname(&u) == 0 ? u.machine : "?");
}

static const char *fs_name(const char *dir)
{
	struct statfs s;
	if (statfs(dir, &s) != 0)
		return "?";
	switch ((unsigned long)s.f_type) {
	case 0x01021994UL:
		return "tmpfs";
	case 0xEF53UL:
		return "ext4";
	case 0x794c7630UL:
		return "overlayfs";
	case 0x58465342UL:
		return "xfs";
	case 0x9123683EUL:
		return "btrfs";
	default:
		return "other";
	}
}

static void print_stream_row(FILE *fp, int w, int h, const char *tool, const stream_result *r)
{
	if (!r->ok) {
		fprintf(fp, "| %dx%d | %s | - | - | - | - | - | - | - | - | %s |\n", w, h, tool,
		        r->note);
		return;
	}
	fprintf(fp, "| %dx%d | %s | %.1f | %.1f | %llu | %llu | %llu | %llu | %llu | %llu | |\n", w,
	        h, tool, r->fps, r->mib_s, r->completed, r->failed, r->incomplete, r->dropped,
	        r->missing_packets, r->resent);
}

static void report(FILE *fp, const opts *o, const char *date, const char *machine,
                   const char *load, const char *rec_dir, stream_result (*sr)[3])
{
	fprintf(fp, "# kogei camera bench: frame rate and recording against the fake GigE Vision "
	            "camera\n\n");
	fprintf(fp, "Command: `%s`  \n", o->command);
	fprintf(fp, "Run: %s on %s (load average %s at the start); Aravis %s; %g s per "
	            "measurement, %g fps asked, Mono16, kogei with %d stream buffers. The "
	            "program is built as `bench/camera/kogei-bench-camera` in the build "
	            "directory (not installed).\n\n",
	        date, machine, load, KG_ARAVIS_VERSION, o->duration, o->rate, o->buffers);
	fprintf(fp,
	        "## How to read\n\n"
	        "- One fake camera (`arv-fake-gv-camera-0.8 -i 127.0.0.1`, a child process) serves "
	        "GigE Vision over loopback inside a private network namespace; kogei's Aravis backend "
	        "(`aravis:127.0.0.1`) and Aravis' own `arv-camera-test-0.8` open it by address, one "
	        "after the other, asked for the same size, pixel format and frame rate, both with "
	        "packet resend on, Aravis' negotiated packet size and its automatic socket buffer.\n"
	        "- **frames/s** and **MiB/s**: complete frames per second in the steady state (kogei: "
	        "frames after the first over the measured time; arv-camera-test: the mean of its "
	        "per-second lines after the first).\n"
	        "- **completed**, **failed**, **incomplete**, **dropped**, **missing packets**, "
	        "**resent**: kogei's kg_stream_stats (dropped = gaps in the frame ids); for "
	        "arv-camera-test its n_completed_buffers, n_failures, -, n_underruns + "
	        "n_missing_frames, n_missing_packets, n_resent_packets.\n"
	        "- The fake camera computes every frame's pattern on the CPU and shares this "
	        "machine's cores with the receiver, so the rate is the pipeline's on this machine, "
	        "not a camera link's; compare the two tools within one run. Machines drift 15-30 %% "
	        "between sessions.\n"
	        "- **Recording**: kogei's receiver with kg_camera_record_start into a temporary "
	        "session: every frame is written to its own file (temporary name, renamed) and its "
	        "line appended to index.jsonl, with one syncfs when recording stops "
	        "(devices/kg_camera.h), so the rate is bounded by the page cache and the disk's "
	        "bandwidth, not by one sync per frame. Frames the recorder cannot keep up with are "
	        "lost for want of a free buffer and show as dropped.\n\n");
	fprintf(fp, "## Streaming\n\n");
	fprintf(fp, "| size | receiver | frames/s | MiB/s | completed | failed | incomplete | "
	            "dropped | missing packets | resent | note |\n");
	fprintf(fp, "|---|---|--:|--:|--:|--:|--:|--:|--:|--:|---|\n");
	for (int i = 0; i < o->nsizes; i++) {
		print_stream_row(fp, o->w[i], o->h[i], "kogei aravis", &sr[i][0]);
		print_stream_row(fp, o->w[i], o->h[i], "arv-camera-test-0.8", &sr[i][1]);
	}
	fprintf(fp, "\n## Recording to disk\n\n");
	fprintf(fp, "Temporary session under `%s` (%s).\n\n", rec_dir, fs_name(rec_dir));
	fprintf(fp, "| size | receiver | frames/s | MiB/s | completed | failed | incomplete | "
	            "dropped | missing packets | resent | note |\n");
	fprintf(fp, "|---|---|--:|--:|--:|--:|--:|--:|--:|--:|---|\n");
	for (int i = 0; i < o->nsizes; i++)
		print_stream_row(fp, o->w[i], o->h[i], "kogei aravis, recording", &sr[i][2]);
}

static int remove_entry(const char *path, const struct stat *st, int flag, struct FTW *ftw)
{
	return remove(path);
}

/* ---- main --------------------------------------------------------------------- */

static int parse_sizes(const char *text, opts *o)
{
	o->nsizes = 0;
	for (const char *p = text; p && *p;) {
		int w, h, n = 0;
		if (o->nsizes == MAX_SIZES || sscanf(p, "%dx%d%n", &w, &h, &n) != 2 || w <= 0 || h <= 0)
			return -1;
		o->w[o->nsizes] = w;
		o->h[o->nsizes++] = h;
		p += n;
		if (*p == ',')
			p++;
		else if (*p)
			return -1;
	}
	return o->nsizes ? 0 : -1;
}

static int bad_value(const char *opt, const char *v)
{
	fprintf(stderr, "kogei-bench-camera: %s %s: bad value\n%s", opt, v ? v : "(missing)",
	        usage);
	return 2;
}

static int parse_args(int argc, char **argv, opts *o)
{
	*o = (opts){.duration = 5, .rate = 1000, .buffers = 8};
	parse_sizes("640x480,2048x2048", o);
	const char *tmp = getenv("TMPDIR");
	o->record_dir = tmp && *tmp ? tmp : "/tmp";
	size_t len = (size_t)snprintf(o->command, sizeof(o->command), "kogei-bench-camera");
	for (int i = 1; i < argc; i++)
		if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) {
			fputs(usage, stdout);
			exit(0);
		}
	for (int i = 1; i < argc; i += 2) {
		const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
		char *end = NULL;
		if (!v)
			return bad_value(a, v);
		if (!strcmp(a, "--duration")) {
			o->duration = strtod(v, &end);
			if (*end || !(o->duration > 0))
				return bad_value(a, v);
		} else if (!strcmp(a, "--rate")) {
			o->rate = strtod(v, &end);
			if (*end || !(o->rate > 0))
				return bad_value(a, v);
		} else if (!strcmp(a, "--buffers")) {
			o->buffers = (int)strtol(v, &end, 10);
			if (*end || o->buffers < 1 || o->buffers > 1024)
				return bad_value(a, v);
		} else if (!strcmp(a, "--sizes")) {
			if (parse_sizes(v, o))
				return bad_value(a, v);
		} else if (!strcmp(a, "--record-dir")) {
			o->record_dir = v;
		} else if (!strcmp(a, "-o")) {
			o->out = v;
		} else {
			fprintf(stderr, "kogei-bench-camera: unknown option '%s'\n%s", a, usage);
			return 2;
		}
		if (len < sizeof(o->command))
			len += (size_t)snprintf(o->command + len, sizeof(o->command) - len, " %s %s", a, v);
	}
	return 0;
}

int main(int argc, char **argv)
{
	opts o;
	int ret = parse_args(argc, argv, &o);
	if (ret)
		return ret;
	if (!getenv(NETNS_ENV))
		return reexec_in_netns(argc, argv);

	char date[64], machine[256];
	time_t now = time(NULL);
	struct tm tm;
	gmtime_r(&now, &tm);
	strftime(date, sizeof(date), "%Y-%m-%d %H:%M UTC", &tm);
	describe_machine(machine, sizeof(machine));
	char load[32] = "?";
	FILE *la = fopen("/proc/loadavg", "r");
	if (la) {
		if (fscanf(la, "%31s", load) != 1)
			snprintf(load, sizeof(load), "?");
		fclose(la);
	}

	char *server_argv[] = {"arv-fake-gv-camera-0.8", "-i", ADDRESS, NULL};
	pid_t server = spawn_quiet(server_argv, -1);
	if (server < 0) {
		fprintf(stderr, "kogei-bench-camera: cannot start arv-fake-gv-camera-0.8 "
		                "(package aravis-tools)\n");
		return 3;
	}
	stream_result sr[MAX_SIZES][3]; /* kogei, arv-camera-test, kogei recording */
	memset(sr, 0, sizeof(sr));
	char session_tpl[4096];
	snprintf(session_tpl, sizeof(session_tpl), "%s/kogei-bench-camera-XXXXXX", o.record_dir);
	int failures = 0;
	for (int i = 0; i < o.nsizes; i++) {
		kg_err err = {{0}};
		fprintf(stderr, "%dx%d: kogei...\n", o.w[i], o.h[i]);
		if (run_stream(&o, o.w[i], o.h[i], NULL, &sr[i][0], &err)) {
			snprintf(sr[i][0].note, sizeof(sr[i][0].note), "%.250s", err.msg);
			failures++;
		}
		fprintf(stderr, "%dx%d: arv-camera-test-0.8...\n", o.w[i], o.h[i]);
		if (run_arv_camera_test(&o, o.w[i], o.h[i], &sr[i][1]))
			failures++;
		fprintf(stderr, "%dx%d: recording...\n", o.w[i], o.h[i]);
		char session[4096];
		snprintf(session, sizeof(session), "%s", session_tpl);
		if (!mkdtemp(session)) {
			snprintf(sr[i][2].note, sizeof(sr[i][2].note), "cannot create a directory in %.180s: %s",
			         o.record_dir, strerror(errno));
			failures++;
			continue;
		}
		if (run_stream(&o, o.w[i], o.h[i], session, &sr[i][2], &err)) {
			snprintf(sr[i][2].note, sizeof(sr[i][2].note), "%.250s", err.msg);
			failures++;
		}
		nftw(session, remove_entry, 16, FTW_DEPTH | FTW_PHYS);
	}
	stop_child(server);

	report(stdout, &o, date, machine, load, o.record_dir, sr);
	if (o.out) {
		kg_outfile of;
		kg_err err = {{0}};
		ret = kg_outfile_open(&of, o.out, 1, &err);
		if (!ret) {
			report(of.fp, &o, date, machine, load, o.record_dir, sr);
			ret = kg_outfile_commit(&of, &err);
		}
		if (ret) {
			fprintf(stderr, "kogei-bench-camera: %s\n", err.msg);
			return 1;
		}
	}
	return failures ? 3 : 0;
}
