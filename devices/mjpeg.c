/* Motion-JPEG frames to 8-bit R'G'B' through libjpeg (libjpeg-turbo in Debian).
 *
 * UVC cameras send MJPEG frames without the Huffman tables (DHT segments): the
 * decoder must fall back to the standard tables of ITU-T T.81 Annex K.3, which
 * libjpeg-turbo does on its own since 1.5. A frame the decoder has to guess at
 * (truncated data, a bad marker: libjpeg's "corrupt data" warnings) is an error, not a
 * picture, because a measurement must not average a damaged frame. */
#include "mjpeg.h"

#include "kg_config.h"

#if HAVE_JPEG
#include <setjmp.h>
#include <stdio.h>
#include <string.h>

#include <jpeglib.h>

typedef struct {
	struct jpeg_error_mgr pub;
	jmp_buf jump;
	char msg[JMSG_LENGTH_MAX];
	int warnings;
} mjpeg_error;

static void on_error(j_common_ptr cinfo)
{
	mjpeg_error *e = (mjpeg_error *)cinfo->err;
	(*cinfo->err->format_message)(cinfo, e->msg);
	longjmp(e->jump, 1);
}

/* Level -1 is a warning about the data (libjpeg keeps decoding with a guess): keep the
 * first as the message; trace messages (level >= 0) are dropped. */
static void on_message(j_common_ptr cinfo, int level)
{
	mjpeg_error *e = (mjpeg_error *)cinfo->err;
	if (level >= 0)
		return;
	if (!e->warnings++)
		(*cinfo->err->format_message)(cinfo, e->msg);
}

int kg_mjpeg_available(void) { return 1; }

int kg_mjpeg_decode(const uint8_t *data, size_t size, int width, int height, uint8_t *rgb,
                    kg_err *err)
{
	kg_check_arg(data && rgb && width > 0 && height > 0, err);
	if (size < 4 || data[0] != 0xFF || data[1] != 0xD8)
		return kg_fail(err, KG_EINVAL,
		               "MJPEG frame of %zu bytes: expected a JPEG stream starting with the "
		               "SOI marker FF D8",
		               size);
	struct jpeg_decompress_struct cinfo;
	mjpeg_error e;
	memset(&e, 0, sizeof(e));
	cinfo.err = jpeg_std_error(&e.pub);
	e.pub.error_exit = on_error;
	e.pub.emit_message = on_message;
	if (setjmp(e.jump)) {
		jpeg_destroy_decompress(&cinfo);
		return kg_fail(err, KG_EINVAL, "MJPEG frame of %zu bytes: %s", size, e.msg);
	}
	jpeg_create_decompress(&cinfo);
	jpeg_mem_src(&cinfo, data, (unsigned long)size);
	jpeg_read_header(&cinfo, TRUE);
	if ((int)cinfo.image_width != width || (int)cinfo.image_height != height) {
		int w = (int)cinfo.image_width, h = (int)cinfo.image_height;
		jpeg_destroy_decompress(&cinfo);
		return kg_fail(err, KG_EINVAL,
		               "MJPEG frame of %zu bytes: the stream is %dx%d, the camera's format "
		               "says %dx%d",
		               size, w, h, width, height);
	}
	cinfo.out_color_space = JCS_RGB;
	cinfo.dct_method = JDCT_ISLOW; /* the accurate integer IDCT: the same on every CPU */
	cinfo.do_fancy_upsampling = TRUE;
	jpeg_start_decompress(&cinfo);
	while (cinfo.output_scanline < cinfo.output_height) {
		JSAMPROW dst = rgb + (size_t)cinfo.output_scanline * (size_t)width * 3;
		jpeg_read_scanlines(&cinfo, &dst, 1);
	}
	jpeg_finish_decompress(&cinfo);
	jpeg_destroy_decompress(&cinfo);
	if (e.warnings)
		return kg_fail(err, KG_EINVAL,
		               "MJPEG frame of %zu bytes is damaged (%d decoder warning%s, first: %s)",
		               size, e.warnings, e.warnings == 1 ? "" : "s", e.msg);
	return 0;
}

#else

int kg_mjpeg_available(void) { return 0; }

int kg_mjpeg_decode(const uint8_t *data, size_t size, int width, int height, uint8_t *rgb,
                    kg_err *err)
{
	(void)data;
	(void)width;
	(void)height;
	(void)rgb;
	return kg_fail(err, KG_ENOTSUP,
	               "MJPEG frame of %zu bytes: this kogei was built without libjpeg "
	               "(install libjpeg-dev and rebuild), so MJPEG cannot be decoded",
	               size);
}

#endif
