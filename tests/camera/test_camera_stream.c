/* Stream bookkeeping in camera.c, driven by the sim camera: dropped frames counted
 * from sequence gaps (drop=N), a camera that stops delivering (stall=N) giving
 * KG_ETIMEDOUT with the counts in the message, buffers that are not given back, and
 * a frame period longer than the pop timeout (realtime=1). */
#include <string.h>

#include "camera_test.h"

static void test_drops(void)
{
	/* drop=4: the sensor loses frames 4, 8, 12, ...; sequence numbers skip them and
	 * timestamps keep the sensor's clock (1/fps per frame, lost ones included). */
	kg_camera *c = cam_open("sim:?width=32&height=24&drop=4&fps=50");
	kg_err e = {{0}};
	cam_must(kg_camera_manual(c, &e), &e, "manual");
	cam_must(kg_camera_start(c, 2, &e), &e, "start");
	uint64_t seq[10];
	double ts[10];
	for (int i = 0; i < 10; i++) {
		kg_frame f;
		cam_must(kg_camera_pop(c, 1000, &f, &e), &e, "pop");
		seq[i] = f.sequence;
		ts[i] = f.timestamp;
		cam_must(kg_camera_push(c, &f, &e), &e, "push");
	}
	uint64_t gaps = 0, multiples = 0;
	for (int i = 1; i < 10; i++) {
		CHECK(seq[i] > seq[i - 1], "sequence increases");
		gaps += seq[i] - seq[i - 1] - 1;
		CHECK_NEAR(ts[i] - ts[i - 1], (double)(seq[i] - seq[i - 1]) / 50.0, 1e-9,
		           "timestamp step follows the sequence");
		CHECK(seq[i] % 4 != 0, "frame %llu should have been lost",
		      (unsigned long long)seq[i]);
	}
	for (uint64_t s = seq[0] + 1; s < seq[9]; s++)
		multiples += s % 4 == 0;
	kg_stream_stats st;
	kg_camera_stats(c, &st);
	CHECK(st.completed == 10, "completed %llu", (unsigned long long)st.completed);
	CHECK(st.dropped == gaps && gaps == multiples && gaps > 0,
	      "dropped %llu, gaps %llu, multiples of 4 %llu", (unsigned long long)st.dropped,
	      (unsigned long long)gaps, (unsigned long long)multiples);

	/* Both buffers held: the next pop says so instead of overwriting one. */
	kg_frame a, b, x;
	cam_must(kg_camera_pop(c, 1000, &a, &e), &e, "pop a");
	cam_must(kg_camera_pop(c, 1000, &b, &e), &e, "pop b");
	CHECK(a.data != b.data, "two buffers");
	CHECK(kg_camera_pop(c, 1000, &x, &e) == KG_EINVAL && strstr(e.msg, "kg_camera_push"),
	      "pop with every buffer held: %s", e.msg);
	cam_must(kg_camera_push(c, &a, &e), &e, "push a");
	CHECK(kg_camera_push(c, &a, &e) == KG_EINVAL, "pushing twice refused");
	cam_must(kg_camera_push(c, &b, &e), &e, "push b");
	kg_camera_stats(c, &st);
	CHECK(st.completed == 12, "stats after restart %llu", (unsigned long long)st.completed);
	/* Restarting the stream resets the counters. */
	cam_must(kg_camera_stop(c, &e), &e, "stop");
	CHECK(kg_camera_pop(c, 10, &x, &e) == KG_EINVAL && strstr(e.msg, "not streaming"),
	      "pop after stop: %s", e.msg);
	cam_must(kg_camera_start(c, 0, &e), &e, "start");
	kg_camera_stats(c, &st);
	CHECK(st.completed == 0 && st.dropped == 0, "counters reset at start");
	kg_camera_free(&c);
}

static void test_stall(void)
{
	kg_camera *c = cam_open("sim:?width=16&height=8&stall=3");
	kg_err e = {{0}};
	cam_must(kg_camera_start(c, 0, &e), &e, "start");
	for (int i = 0; i < 3; i++) {
		kg_frame f;
		cam_must(kg_camera_pop(c, 1000, &f, &e), &e, "pop");
		cam_must(kg_camera_push(c, &f, &e), &e, "push");
	}
	for (int k = 1; k <= 2; k++) {
		kg_frame f;
		int ret = kg_camera_pop(c, 20, &f, &e);
		char want[64];
		snprintf(want, sizeof(want), "3 complete, 0 dropped, 0 incomplete, 0 failed, %d "
		         "timeouts", k);
		CHECK(ret == KG_ETIMEDOUT && strstr(e.msg, want) && strstr(e.msg, "20 ms") &&
		          strstr(e.msg, "camera 'sim:"),
		      "stalled pop %d: %d '%s'", k, ret, e.msg);
	}
	kg_stream_stats st;
	kg_camera_stats(c, &st);
	CHECK(st.completed == 3 && st.timeouts == 2, "completed %llu timeouts %llu",
	      (unsigned long long)st.completed, (unsigned long long)st.timeouts);
	kg_camera_free(&c);
}

static void test_realtime(void)
{
	/* 0.5 fps in real time: a 10 ms timeout expires before the first frame. */
	kg_camera *c = cam_open("sim:?width=16&height=8&fps=0.5&realtime=1");
	kg_err e = {{0}};
	cam_must(kg_camera_manual(c, &e), &e, "manual");
	cam_must(kg_camera_start(c, 0, &e), &e, "start");
	kg_frame f;
	int ret = kg_camera_pop(c, 10, &f, &e);
	CHECK(ret == KG_ETIMEDOUT && strstr(e.msg, "0 complete"), "realtime timeout: %d %s", ret,
	      e.msg);
	/* At 1000 fps the frame comes well inside the timeout. */
	cam_must(kg_camera_set(c, KG_FEAT_FRAME_RATE, 1000, NULL, &e), &e, "fps");
	cam_must(kg_camera_set(c, KG_FEAT_EXPOSURE_US, 100, NULL, &e), &e, "exposure");
	ret = kg_camera_pop(c, 5000, &f, &e);
	CHECK(ret == 0 && f.sequence == 1, "realtime frame: %d %s", ret, e.msg);
	if (!ret)
		kg_camera_push(c, &f, &e);
	kg_camera_free(&c);
}

int main(void)
{
	test_drops();
	test_stall();
	test_realtime();
	return kg_test_done("test_camera_stream");
}
