/* OpenCV's mcc ColorChecker detector behind chart_mcc.h. Only the chart's box is
 * taken from mcc: chart_detect.c places and samples the patches itself. */
#include <math.h>
#include <pthread.h>
#include <string.h>

#include <exception>
#include <new>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/mcc.hpp>

#include "chart_mcc.h"

/* The 8-bit BGR copy mcc sees: value / white through the sRGB curve (a lookup
 * table of 4096 steps over 0..1). */
static void encode_bgr8(const float *data, int width, int height, int channels, double white,
                        cv::Mat &out)
{
	enum { STEPS = 4096 };
	unsigned char lut[STEPS];
	for (int b = 0; b < STEPS; b++) {
		double v = (b + 0.5) / STEPS;
		double e = v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1 / 2.4) - 0.055;
		lut[b] = (unsigned char)lrint(fmin(fmax(e, 0), 1) * 255);
	}
	double k = STEPS / (white > 0 ? white : 1.0);
	out.create(height, width, CV_8UC3);
	for (int y = 0; y < height; y++) {
		const float *src = data + (size_t)y * width * channels;
		unsigned char *dst = out.ptr<unsigned char>(y);
		for (int x = 0; x < width; x++) {
			for (int c = 0; c < 3; c++) {
				double v = src[(size_t)x * channels + (channels == 3 ? c : 0)] * k;
				int b = !(v > 0) ? 0 : v >= STEPS - 1 ? STEPS - 1 : (int)v;
				dst[3 * x + 2 - c] = lut[b];
			}
		}
	}
}

/* One conversion to Lab of each depth mcc converts: OpenCV builds its tables then
 * (not safely from two threads at once: pthread_once). */
static pthread_once_t lab_once = PTHREAD_ONCE_INIT;

static void lab_tables(void)
{
	try {
		cv::Mat b8(2, 2, CV_8UC3, cv::Scalar(10, 120, 240)), f32(2, 2, CV_32FC3,
		                                                        cv::Scalar(0.1, 0.5, 0.9)), lab;
		cv::cvtColor(b8, lab, cv::COLOR_BGR2Lab);
		cv::cvtColor(f32, lab, cv::COLOR_BGR2Lab);
		cv::cvtColor(b8, lab, cv::COLOR_RGB2Lab);
	} catch (...) {
		/* the detector's own call will say what failed */
	}
}

static void *warm_main(void *)
{
	pthread_once(&lab_once, lab_tables);
	return NULL;
}

/* The warm-up thread is joined, never detached: a thread still inside OpenCV when the
 * process exits meets OpenCV's thread-local storage already destroyed ("pure virtual
 * method called", tlsSlotsSize > slotIdx). 0 not started, 1 running, 2 joined. */
static pthread_mutex_t warm_lock = PTHREAD_MUTEX_INITIALIZER;
static int warm_state;
static pthread_t warm_tid;

extern "C" void kg_mcc_warm_up(void)
{
	pthread_mutex_lock(&warm_lock);
	if (warm_state == 0 && pthread_create(&warm_tid, NULL, warm_main, NULL) == 0)
		warm_state = 1;
	pthread_mutex_unlock(&warm_lock);
}

extern "C" void kg_mcc_warm_wait(void)
{
	pthread_mutex_lock(&warm_lock);
	if (warm_state == 1) {
		pthread_join(warm_tid, NULL);
		warm_state = 2;
	}
	pthread_mutex_unlock(&warm_lock);
}

extern "C" int kg_mcc_find_colorcheckers(const float *data, int width, int height,
                                         int channels, double white, int threads, int max,
                                         double (*boxes)[4][2], double *costs, int *found,
                                         kg_err *err)
{
	*found = 0;
	if (!data || width <= 0 || height <= 0 || (channels != 1 && channels != 3) || max < 1)
		return kg_fail(err, KG_EINVAL, "mcc: invalid image (%d x %d x %d)", width, height,
		               channels);
	int previous_threads = cv::getNumThreads();
	int ret = 0;
	pthread_once(&lab_once, lab_tables);
	try {
		cv::Mat bgr;
		encode_bgr8(data, width, height, channels, white, bgr);
		if (threads > 0)
			cv::setNumThreads(threads);
		cv::Ptr<cv::mcc::CCheckerDetector> detector = cv::mcc::CCheckerDetector::create();
		bool any = detector->process(bgr, cv::mcc::MCC24, max);
		std::vector<cv::Ptr<cv::mcc::CChecker>> list;
		if (any) {
			/* mcc's best first, then its other candidates */
			cv::Ptr<cv::mcc::CChecker> best = detector->getBestColorChecker();
			list.push_back(best);
			for (const cv::Ptr<cv::mcc::CChecker> &c : detector->getListColorChecker())
				if (c && c != best)
					list.push_back(c);
		}
		for (size_t i = 0; i < list.size() && *found < max; i++) {
			std::vector<cv::Point2f> corners;
			if (list[i])
				corners = list[i]->getBox();
			if (corners.size() != 4)
				continue;
			for (int k = 0; k < 4; k++) {
				boxes[*found][k][0] = corners[k].x + 0.5;
				boxes[*found][k][1] = corners[k].y + 0.5;
			}
			if (costs)
				costs[*found] = list[i]->getCost();
			++*found;
		}
		if (!*found)
			ret = kg_fail(err, KG_ENOENT, "OpenCV mcc found no ColorChecker 24 in the image "
			              "(%d x %d): is the whole chart in view, lit and in focus?", width,
			              height);
	} catch (const std::bad_alloc &) {
		ret = kg_fail(err, KG_ENOMEM, "mcc: out of memory");
	} catch (const std::exception &e) {
		ret = kg_fail(err, KG_EIO, "mcc: OpenCV failed: %s", e.what());
	}
	if (threads > 0)
		cv::setNumThreads(previous_threads);
	return ret;
}

extern "C" int kg_mcc_find_colorchecker(const float *data, int width, int height, int channels,
                                        double white, int threads, double box[4][2],
                                        double *cost, kg_err *err)
{
	int found = 0;
	double boxes[1][4][2], costs[1] = {0};
	int ret = kg_mcc_find_colorcheckers(data, width, height, channels, white, threads, 1,
	                                    boxes, costs, &found, err);
	if (!ret) {
		memcpy(box, boxes[0], sizeof(boxes[0]));
		if (cost)
			*cost = costs[0];
	}
	return ret;
}
