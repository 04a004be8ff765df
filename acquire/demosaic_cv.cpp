/* OpenCV's demosaicing behind demosaic_cv.h. */
#include <string.h>

#include <exception>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "demosaic_cv.h"

extern "C" int kg_cv_demosaic_u16(const uint16_t *mosaic, int width, int height,
                                  const char *cfa, uint16_t *rgb, kg_err *err)
{
	int code;
	if (!strcmp(cfa, "RGGB"))
		code = cv::COLOR_BayerRGGB2RGB;
	else if (!strcmp(cfa, "GRBG"))
		code = cv::COLOR_BayerGRBG2RGB;
	else if (!strcmp(cfa, "GBRG"))
		code = cv::COLOR_BayerGBRG2RGB;
	else if (!strcmp(cfa, "BGGR"))
		code = cv::COLOR_BayerBGGR2RGB;
	else
		return kg_fail(err, KG_EINVAL, "demosaic: CFA '%s': expected RGGB, GRBG, GBRG or BGGR",
		               cfa);
	if (width < 2 || height < 2)
		return kg_fail(err, KG_EINVAL, "demosaic: %dx%d: expected at least 2x2", width,
		               height);
	try {
		cv::Mat in(height, width, CV_16UC1, const_cast<uint16_t *>(mosaic));
		cv::Mat out(height, width, CV_16UC3, rgb);
		cv::demosaicing(in, out, code, 3);
		if (out.data != reinterpret_cast<uchar *>(rgb)) /* OpenCV reallocated */
			return kg_fail(err, KG_EIO, "demosaic: OpenCV did not write the given buffer");
	} catch (const std::exception &e) {
		return kg_fail(err, KG_EIO, "demosaic: OpenCV failed: %s", e.what());
	}
	return 0;
}

extern "C" const char *kg_cv_demosaic_name(void)
{
	return "OpenCV " CV_VERSION " cv::demosaicing bilinear (COLOR_Bayer*2RGB)";
}
