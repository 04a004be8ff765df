/* The Aravis backend over real GigE Vision (GVCP control, GVSP stream) on loopback,
 * opened by address without discovery. Run inside a private network namespace
 * (netns.sh), since Aravis may broadcast.
 *
 *   test_aravis_gv inprocess   Aravis' fake GigE Vision camera served in this process
 *                              on 127.0.0.1 with frames injected through its fill
 *                              callback: they arrive byte for byte over GVSP with the
 *                              packet size asked for, the counters say N complete and
 *                              nothing failed, missing or dropped; then the camera stops
 *                              sending and a pop gives KG_ETIMEDOUT with the counts; then
 *                              it loses packets: frames with holes come out INCOMPLETE,
 *                              counted, and the ones delivered OK are intact.
 *   test_aravis_gv kill        arv-fake-gv-camera-0.8 as a child process, killed with
 *                              SIGKILL mid-stream: the next pops time out
 *                              (KG_ETIMEDOUT) naming the counts, and once Aravis'
 *                              heartbeat gives up (about 6 s) they fail with KG_EIO
 *                              "control lost"; closing takes Aravis' GVCP retries
 *                              (about 5 s) and does not hang. */
#include <net/if.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "aravis_inject.h"
#include "kg_camera.h"
#include "kg_test.h"

extern char **environ;

/* GigE Vision bootstrap register SCPS0 (stream channel packet size), low 16 bits. */
#define GVBS_SCPS0 0x0d04

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void print_stats(const char *what, const kg_stream_stats *st)
{
	printf("%s: completed %llu failed %llu incomplete %llu dropped %llu resent %llu "
	       "missing packets %llu timeouts %llu\n",
	       what, (unsigned long long)st->completed, (unsigned long long)st->failed,
	       (unsigned long long)st->incomplete, (unsigned long long)st->dropped,
	       (unsigned long long)st->resent, (unsigned long long)st->missing_packets,
	       (unsigned long long)st->timeouts);
}

/* 1 when loopback is the only network interface (a private namespace): only then may
 * a test let Aravis discover. */
static int only_loopback(void)
{
	struct if_nameindex *ifs = if_nameindex();
	int ok = ifs != NULL;
	for (struct if_nameindex *i = ifs; ok && i->if_index; i++)
		ok = !strcmp(i->if_name, "lo");
	if (ifs)
		if_freenameindex(ifs);
	return ok;
}

typedef struct listed {
	int n;
	char uri[4][128], transport[4][32], serial[4][64];
} listed;

static void on_found(void *user, const char *uri, const char *model, const char *serial,
                     const char *transport)
{
	listed *l = user;
	if (strncmp(uri, "aravis:", 7) || l->n == 4)
		return;
	snprintf(l->uri[l->n], sizeof(l->uri[0]), "%s", uri);
	snprintf(l->transport[l->n], sizeof(l->transport[0]), "%s", transport);
	snprintf(l->serial[l->n++], sizeof(l->serial[0]), "%s", serial);
}

/* Discovery, allowed here because loopback is the only interface: "all" finds the fake
 * GigE Vision camera and opens it by the id it was listed under; "usb" leaves GigE
 * Vision out. */
static void check_discovery(void)
{
	if (!only_loopback()) {
		printf("discovery not checked: interfaces other than lo are present\n");
		return;
	}
	listed l = {0};
	setenv("KOGEI_CAMERA_DISCOVERY", "all", 1);
	kg_camera_enumerate(on_found, NULL, &l);
	CHECK(l.n == 1 && !strcmp(l.transport[0], "GigE Vision") && !strcmp(l.serial[0], "KG01"),
	      "discovery found %d camera(s): %s %s %s", l.n, l.n ? l.uri[0] : "",
	      l.n ? l.transport[0] : "", l.n ? l.serial[0] : "");
	if (l.n == 1) {
		kg_err err = {{0}};
		kg_camera *c = NULL;
		int ret = kg_camera_open(l.uri[0], &c, &err);
		CHECK(ret == 0 && !strcmp(kg_camera_get_info(c)->serial, "KG01"), "open %s: %s",
		      l.uri[0], err.msg);
		kg_camera_free(&c);
	}
	listed u = {0};
	setenv("KOGEI_CAMERA_DISCOVERY", "usb", 1);
	kg_camera_enumerate(on_found, NULL, &u);
	for (int i = 0; i < u.n; i++)
		CHECK(strcmp(u.transport[i], "GigE Vision"), "usb-only discovery listed %s", u.uri[i]);
	setenv("KOGEI_CAMERA_DISCOVERY", "none", 1);
}

/* The fake drops GVSP packets at random (and cannot resend them): frames with holes
 * come out INCOMPLETE and are counted with the missing packets; every frame delivered
 * OK is still its injected frame byte for byte (its number read from its header). */
static void check_lossy(kg_camera *c, ArvGvFakeCamera *gv)
{
	kg_err err = {{0}};
	int ret = kg_camera_stop(c, &err);
	g_object_set(gv, "gvsp-lost-ratio", 0.002, NULL);
	if (!ret)
		ret = kg_camera_start(c, 8, &err);
	CHECK(ret == 0, "lossy start: %s", err.msg);
	int ok = 0, bad = 0, corrupt = 0;
	uint64_t last_k = 0;
	for (int i = 0; i < 40 && !ret; i++) {
		kg_frame f;
		if ((ret = kg_camera_pop(c, 2000, &f, &err)))
			break;
		if (f.status == KG_FRAME_OK) {
			uint64_t k;
			memcpy(&k, f.data, 8);
			CHECK(inject_matches(&f, k), "lossy: frame %d (injected %llu) delivered OK but "
			      "differs", i, (unsigned long long)k);
			CHECK(!ok || k > last_k, "lossy: frame %llu after %llu", (unsigned long long)k,
			      (unsigned long long)last_k);
			last_k = k;
			ok++;
		} else {
			corrupt += f.status == KG_FRAME_CORRUPT;
			bad++;
		}
		kg_camera_push(c, &f, NULL);
	}
	CHECK(ret == 0, "lossy: %s", err.msg);
	kg_stream_stats st;
	kg_camera_stats(c, &st);
	print_stats("lossy", &st);
	printf("lossy: %d frames OK, %d incomplete\n", ok, bad);
	CHECK(bad > 0 && !corrupt && st.incomplete == (uint64_t)bad && st.completed == (uint64_t)ok &&
	          st.missing_packets > 0,
	      "lossy: %d OK, %d not OK (%d corrupt): the counts above should match", ok, bad,
	      corrupt);
	g_object_set(gv, "gvsp-lost-ratio", 0.0, NULL);
}

static int run_inprocess(void)
{
	ArvGvFakeCamera *gv = arv_gv_fake_camera_new("127.0.0.1", "KG01");
	if (!gv || !arv_gv_fake_camera_is_running(gv))
		kg_test_skip("the fake GigE Vision camera cannot listen on 127.0.0.1");
	inject in;
	inject_attach(&in, arv_gv_fake_camera_get_fake_camera(gv));

	kg_err err = {{0}};
	kg_camera *c = NULL;
	int ret = kg_camera_open("aravis:127.0.0.1?packet_size=1024&socket_buffer=4194304", &c,
	                         &err);
	CHECK(ret == 0, "open: %s", err.msg);
	if (ret) {
		g_object_unref(gv);
		return kg_test_done("aravis-gv");
	}
	const kg_camera_info *info = kg_camera_get_info(c);
	CHECK(!strcmp(info->transport, "GigE Vision") && !strcmp(info->serial, "KG01") &&
	          !strcmp(info->model, "Fake"),
	      "info: transport '%s' serial '%s' model '%s'", info->transport, info->serial,
	      info->model);
	kg_feature_info fi;
	ret = kg_camera_feature_info(c, KG_FEAT_EXPOSURE_US, &fi, &err);
	CHECK(ret == 0 && !strcmp(fi.native, "ExposureTimeAbs"), "exposure over GVCP: '%s' %s",
	      fi.native, err.msg);
	ret = kg_camera_set(c, KG_FEAT_GAIN, 2, NULL, &err);
	CHECK(ret == 0, "gain over GVCP: %s", err.msg);

	const int n = 30;
	kg_frame_format want = {.pixfmt = KG_PIX_MONO16, .width = 640, .height = 480};
	kg_frame_format got;
	ret = kg_camera_set_format(c, &want, &got, &err);
	if (!ret)
		ret = kg_camera_set(c, KG_FEAT_FRAME_RATE, 100, NULL, &err);
	if (!ret)
		ret = kg_camera_start(c, 8, &err);
	CHECK(ret == 0, "set up and start: %s", err.msg);
	guint32 scps = 0;
	arv_fake_camera_read_register(in.fake, GVBS_SCPS0, &scps);
	CHECK((scps & 0xffff) == 1024, "packet size register %u, asked for 1024", scps & 0xffff);
	for (int k = 0; k < n && !ret; k++) {
		kg_frame f;
		ret = kg_camera_pop(c, 2000, &f, &err);
		CHECK(ret == 0, "pop %d: %s", k, err.msg);
		if (ret)
			break;
		CHECK(f.status == KG_FRAME_OK, "frame %d status %d", k, f.status);
		CHECK(inject_matches(&f, (uint64_t)k), "frame %d is not the injected frame", k);
		kg_camera_push(c, &f, &err);
	}
	kg_stream_stats st;
	kg_camera_stats(c, &st);
	print_stats("streamed", &st);
	CHECK(st.completed == (uint64_t)n && !st.failed && !st.incomplete && !st.dropped &&
	          !st.missing_packets && !st.timeouts,
	      "after %d frames: see the counts above", n);

	/* The camera stops sending (acquisition stopped behind kogei's back): what was
	 * already on its way may still come, then a pop times out and says how far the
	 * stream got. */
	arv_fake_camera_write_register(in.fake, ARV_FAKE_CAMERA_REGISTER_ACQUISITION, 0);
	int extra = 0;
	for (; extra < 16; extra++) {
		kg_frame f;
		ret = kg_camera_pop(c, 500, &f, &err);
		if (ret)
			break;
		kg_camera_push(c, &f, NULL);
	}
	CHECK(ret == KG_ETIMEDOUT, "after the camera stopped: %d %s", ret, err.msg);
	printf("after the camera stopped: %d more frame(s), then: %s\n", extra, err.msg);
	char counts[64];
	snprintf(counts, sizeof(counts), "%d complete", n + extra);
	CHECK(strstr(err.msg, "no frame within 500 ms") && strstr(err.msg, counts),
	      "the timeout message should give the counts (%s): %s", counts, err.msg);
	kg_camera_stats(c, &st);
	CHECK(st.timeouts == 1 && !st.failed, "timeouts %llu failed %llu",
	      (unsigned long long)st.timeouts, (unsigned long long)st.failed);
	check_lossy(c, gv);
	kg_camera_free(&c);
	check_discovery();
	g_object_unref(gv);
	arv_shutdown();
	return kg_test_done("aravis-gv");
}

/* The first directory of PATH holding prog, or NULL. */
static char *find_in_path(const char *prog)
{
	const char *path = getenv("PATH");
	static char buf[4096];
	for (const char *p = path; p && *p;) {
		const char *colon = strchr(p, ':');
		size_t len = colon ? (size_t)(colon - p) : strlen(p);
		snprintf(buf, sizeof(buf), "%.*s/%s", (int)len, p, prog);
		if (access(buf, X_OK) == 0)
			return buf;
		p = colon ? colon + 1 : NULL;
	}
	return NULL;
}

static int run_kill(void)
{
	char *server = find_in_path("arv-fake-gv-camera-0.8");
	if (!server)
		kg_test_skip("arv-fake-gv-camera-0.8 (aravis-tools) is not installed");
	char *argv[] = {server, "-i", "127.0.0.1", "-s", "KGKILL", NULL};
	pid_t pid;
	if (posix_spawn(&pid, server, NULL, NULL, argv, environ) != 0)
		kg_test_skip("cannot start arv-fake-gv-camera-0.8");

	kg_err err = {{0}};
	kg_camera *c = NULL;
	int ret = -1;
	double t0 = now_s();
	while (now_s() - t0 < 10 && (ret = kg_camera_open("aravis:127.0.0.1", &c, &err)))
		usleep(100000);
	CHECK(ret == 0, "the fake camera never answered: %s", err.msg);
	if (ret) {
		kill(pid, SIGKILL);
		waitpid(pid, NULL, 0);
		return kg_test_done("aravis-gv-lost");
	}
	CHECK(!strcmp(kg_camera_get_info(c)->serial, "KGKILL"), "serial '%s'",
	      kg_camera_get_info(c)->serial);
	kg_frame_format want = {.pixfmt = KG_PIX_MONO8, .width = 640, .height = 480};
	ret = kg_camera_set_format(c, &want, NULL, &err);
	if (!ret)
		ret = kg_camera_set(c, KG_FEAT_FRAME_RATE, 50, NULL, &err);
	if (!ret)
		ret = kg_camera_start(c, 4, &err);
	CHECK(ret == 0, "set up and start: %s", err.msg);
	const int before = 10;
	for (int k = 0; k < before && !ret; k++) {
		kg_frame f;
		ret = kg_camera_pop(c, 2000, &f, &err);
		CHECK(ret == 0 && f.status == KG_FRAME_OK, "pop %d: %d %s", k, ret, err.msg);
		if (!ret)
			kg_camera_push(c, &f, NULL);
	}
	kill(pid, SIGKILL);
	waitpid(pid, NULL, 0);

	int extra = 0;
	for (ret = 0; extra < 20 && !ret; extra++) {
		kg_frame f;
		ret = kg_camera_pop(c, 300, &f, &err);
		if (!ret)
			kg_camera_push(c, &f, NULL);
	}
	CHECK(ret == KG_ETIMEDOUT || ret == KG_EIO, "after the kill: %d %s", ret, err.msg);
	CHECK(strstr(err.msg, "complete"), "the message should give the counts: %s", err.msg);
	printf("after the kill: %s\n", err.msg);
	/* Aravis' heartbeat notices the camera is gone: pops then say so. */
	double tk = now_s();
	while (ret == KG_ETIMEDOUT && now_s() - tk < 20) {
		kg_frame f;
		ret = kg_camera_pop(c, 300, &f, &err);
	}
	printf("%.1f s later: %d %s\n", now_s() - tk, ret, err.msg);
	CHECK(ret == KG_EIO && strstr(err.msg, "control lost") && strstr(err.msg, "complete frames"),
	      "a lost camera should give KG_EIO naming the control loss and the counts: %d %s",
	      ret, err.msg);
	kg_stream_stats st;
	kg_camera_stats(c, &st);
	print_stats("killed", &st);
	CHECK(st.completed >= (uint64_t)before, "completed %llu < %d", (unsigned long long)st.completed,
	      before);
	double t1 = now_s();
	kg_camera_free(&c);
	printf("closing the lost camera took %.1f s\n", now_s() - t1);
	arv_shutdown();
	return kg_test_done("aravis-gv-lost");
}

int main(int argc, char **argv)
{
	if (argc == 2 && !strcmp(argv[1], "inprocess"))
		return run_inprocess();
	if (argc == 2 && !strcmp(argv[1], "kill"))
		return run_kill();
	fprintf(stderr, "usage: test_aravis_gv inprocess|kill (inside netns.sh)\n");
	return 1;
}
