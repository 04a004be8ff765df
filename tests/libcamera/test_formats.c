/* The libcamera format table (devices/libcamera/lc_formats.h):
 * - its names and fourcc codes agree with libcamera's own (PixelFormat::fromString and
 *   toString of the installed libcamera); a name this libcamera does not know must at
 *   least be unknown to it as a code too, and every raw (Bayer) entry must be known;
 * - libcamera's packed formats (CSI-2, IPU3) are refused;
 * - kogei -> libcamera -> kogei round-trips for every format kg_pixfmt_parse accepts,
 *   and libcamera -> kogei -> libcamera for every entry, the preferred entry of a
 *   request needing no byte swap;
 * - frame formats keep libcamera's stride, and the RGB888 copy puts red first. */
#include <stdio.h>
#include <string.h>

#include "kg_camera.h"
#include "kg_test.h"

#if HAVE_LIBCAMERA
#include "lc_formats.h"
#include "lc_shim.h"

static void check_against_libcamera(const kg_lc_format *t, int n)
{
	int unknown = 0;
	for (int i = 0; i < n; i++) {
		uint32_t fourcc = 0;
		uint64_t modifier = 0;
		char text[5], name[64];
		kg_lc_fourcc_text(t[i].fourcc, text);
		kg_lc_format_name(t[i].fourcc, 0, name, sizeof(name));
		if (kg_lc_format_parse(t[i].name, &fourcc, &modifier) == 0) {
			CHECK(fourcc == t[i].fourcc && modifier == 0,
			      "%s: table has %s, libcamera %08x modifier %llx", t[i].name, text,
			      (unsigned)fourcc, (unsigned long long)modifier);
			CHECK(!strcmp(name, t[i].name), "libcamera calls %s '%s', the table '%s'", text,
			      name, t[i].name);
		} else {
			/* unknown to this libcamera (newer than it): its code must be unknown too */
			char expect[8];
			snprintf(expect, sizeof(expect), "<%s>", text);
			CHECK(!strcmp(name, expect), "libcamera does not parse '%s' but names %s '%s'",
			      t[i].name, text, name);
			CHECK(!t[i].raw, "raw format %s unknown to libcamera %s", t[i].name,
			      kg_lc_version());
			printf("note: libcamera %s does not know %s (%s)\n", kg_lc_version(), t[i].name,
			       text);
			unknown++;
		}
		for (int j = 0; j < i; j++)
			CHECK(t[j].fourcc != t[i].fourcc, "%s and %s share a fourcc", t[j].name,
			      t[i].name);
	}
	CHECK(unknown < n, "libcamera knows none of the table");

	/* packed Bayer and mono, as libcamera defines them, are not taken */
	static const char *const packed[] = {"SRGGB10_CSI2P", "SBGGR12_CSI2P", "R10_CSI2P",
	                                     "SGRBG10_IPU3"};
	for (size_t i = 0; i < sizeof(packed) / sizeof(packed[0]); i++) {
		uint32_t fourcc;
		uint64_t modifier;
		if (kg_lc_format_parse(packed[i], &fourcc, &modifier))
			continue;
		CHECK(modifier != 0, "%s has no modifier in libcamera", packed[i]);
		CHECK(kg_lc_format_find(fourcc, modifier) == NULL, "packed %s is taken", packed[i]);
	}
}

/* kogei's name -> libcamera candidates -> back to kogei. */
static void check_kogei_round_trip(void)
{
	static const char *const fam[] = {"mono", "bayer", "bayer_rggb", "bayer_grbg",
	                                  "bayer_gbrg", "bayer_bggr", "rgb"};
	static const int depths[] = {8, 10, 12, 14, 16};
	int deliverable = 0;
	for (size_t i = 0; i < sizeof(fam) / sizeof(fam[0]); i++)
		for (size_t k = 0; k < sizeof(depths) / sizeof(depths[0]); k++) {
			char text[32], cfa[5];
			kg_pixfmt p;
			int bits;
			snprintf(text, sizeof(text), "%s%d", fam[i], depths[k]);
			if (kg_pixfmt_parse(text, &p, &bits, cfa, NULL))
				continue; /* not a kogei format (rgb10 ...) */
			uint32_t cand[32];
			int n = kg_lc_formats_for(p, bits, cfa, cand, 32);
			int table_n;
			const kg_lc_format *t = kg_lc_format_table(&table_n);
			int expected = 0;
			for (int j = 0; j < table_n; j++)
				expected += t[j].pixfmt == p && t[j].bits == bits &&
				            (!cfa[0] || !strcmp(t[j].cfa, cfa));
			CHECK(n == expected, "%s: %d candidates, %d table entries deliver it", text, n,
			      expected);
			for (int j = 0; j < n; j++) {
				const kg_lc_format *f = kg_lc_format_find(cand[j], 0);
				CHECK(f != NULL, "%s: candidate %08x not in the table", text, (unsigned)cand[j]);
				if (!f)
					continue;
				CHECK(f->pixfmt == p && f->bits == bits && (!cfa[0] || !strcmp(f->cfa, cfa)),
				      "%s: candidate %s is %s %d bits %s", text, f->name,
				      kg_pixfmt_name(f->pixfmt), f->bits, f->cfa);
				CHECK(f->raw == (p == KG_PIX_BAYER8 || p == KG_PIX_BAYER16),
				      "%s: %s raw flag %d", text, f->name, f->raw);
				if (j == 0)
					CHECK(!f->swap_rb, "%s: preferred %s needs a byte swap", text, f->name);
			}
			deliverable += n > 0;
			if (!cfa[0] && (p == KG_PIX_BAYER8 || p == KG_PIX_BAYER16))
				CHECK(n == 0 || n == 4, "%s: %d Bayer orders, expected all 4", text, n);
		}
	CHECK(deliverable > 0, "no kogei format is deliverable");
}

/* each entry -> kogei request -> candidates contain it, first candidate equivalent */
static void check_libcamera_round_trip(const kg_lc_format *t, int n)
{
	for (int i = 0; i < n; i++) {
		CHECK(kg_lc_format_find(t[i].fourcc, 0) == &t[i], "%s not found by its fourcc",
		      t[i].name);
		CHECK(kg_lc_format_find(t[i].fourcc, 1ull << 56 | 1) == NULL,
		      "%s with a modifier is taken", t[i].name);
		uint32_t cand[32];
		int m = kg_lc_formats_for(t[i].pixfmt, t[i].bits, t[i].cfa, cand, 32);
		int has = 0;
		for (int j = 0; j < m; j++)
			has |= cand[j] == t[i].fourcc;
		CHECK(has, "%s is not among the candidates for its own kogei format", t[i].name);
		const kg_lc_format *first = m ? kg_lc_format_find(cand[0], 0) : NULL;
		CHECK(first && first->pixfmt == t[i].pixfmt && first->bits == t[i].bits &&
		          !strcmp(first->cfa, t[i].cfa) && !first->swap_rb,
		      "%s: preferred candidate %s differs", t[i].name, first ? first->name : "none");
		/* any depth of the family: deepest first */
		m = kg_lc_formats_for(t[i].pixfmt, 0, t[i].cfa, cand, 32);
		for (int j = 1; j < m; j++) {
			const kg_lc_format *a = kg_lc_format_find(cand[j - 1], 0);
			const kg_lc_format *b = kg_lc_format_find(cand[j], 0);
			CHECK(a && b && a->bits >= b->bits, "%s family: %s before %s", t[i].name,
			      a ? a->name : "?", b ? b->name : "?");
		}
		/* Bayer carries its pattern, nothing else has one */
		int bayer = t[i].pixfmt == KG_PIX_BAYER8 || t[i].pixfmt == KG_PIX_BAYER16;
		CHECK(bayer == (t[i].cfa[0] != 0), "%s: cfa '%s'", t[i].name, t[i].cfa);
		if (bayer) { /* libcamera names Bayer S<pattern><bits> */
			char expect[16];
			snprintf(expect, sizeof(expect), "S%s%d", t[i].cfa, t[i].bits);
			CHECK(!strcmp(expect, t[i].name), "%s: pattern %s bits %d", t[i].name, t[i].cfa,
			      t[i].bits);
		}
	}
}

static void check_frame_formats(const kg_lc_format *t, int n)
{
	for (int i = 0; i < n; i++) {
		kg_frame_format f;
		int bpp = kg_pixfmt_bytes_per_pixel(t[i].pixfmt);
		unsigned stride = (unsigned)(640 * (bpp ? bpp : 1) + 64);
		kg_lc_frame_format(&t[i], 640, 480, stride, 123456, &f);
		CHECK(f.pixfmt == t[i].pixfmt && f.width == 640 && f.height == 480 &&
		          f.bits == t[i].bits && !strcmp(f.cfa, t[i].cfa),
		      "%s: frame format %s %dx%d bits %d cfa %s", t[i].name, kg_pixfmt_name(f.pixfmt),
		      f.width, f.height, f.bits, f.cfa);
		if (t[i].pixfmt == KG_PIX_MJPEG)
			CHECK(f.size == 123456, "%s: size %zu, libcamera's frame size 123456", t[i].name,
			      f.size);
		else
			CHECK(f.stride == stride && f.size == (size_t)stride * 480,
			      "%s: stride %zu size %zu, libcamera's stride %u", t[i].name, f.stride,
			      f.size, stride);
		/* a stride shorter than a row is libcamera's "unknown": keep the tight one */
		kg_lc_frame_format(&t[i], 640, 480, 0, 0, &f);
		if (bpp)
			CHECK(f.stride == (size_t)(640 * bpp), "%s: stride %zu without libcamera's",
			      t[i].name, f.stride);
	}
}

static void check_swap(void)
{
	/* 2x2 pixels, rows 8 bytes apart; memory B, G, R per pixel */
	const uint8_t src[16] = {1, 2, 3, 4, 5, 6, 99, 99, 7, 8, 9, 10, 11, 12, 99, 99};
	uint8_t dst[16];
	memset(dst, 0, sizeof(dst));
	kg_lc_swap_rb(src, dst, 2, 2, 8);
	const uint8_t expect[16] = {3, 2, 1, 6, 5, 4, 0, 0, 9, 8, 7, 12, 11, 10, 0, 0};
	CHECK(!memcmp(dst, expect, sizeof(dst)), "RGB888 to rgb8: first pixel %d %d %d",
	      dst[0], dst[1], dst[2]);
	int n;
	const kg_lc_format *t = kg_lc_format_table(&n);
	for (int i = 0; i < n; i++)
		CHECK(!t[i].swap_rb || (t[i].pixfmt == KG_PIX_RGB8 && !strcmp(t[i].name, "RGB888")),
		      "%s is marked for a red/blue swap", t[i].name);
}
#endif

int main(void)
{
#if !HAVE_LIBCAMERA
	kg_test_skip("the libcamera backend is not built (pkg-config libcamera and a C++ "
	             "compiler are needed)");
	return 77;
#else
	int n;
	const kg_lc_format *t = kg_lc_format_table(&n);
	CHECK(n > 0, "empty table");
	check_against_libcamera(t, n);
	check_kogei_round_trip();
	check_libcamera_round_trip(t, n);
	check_frame_formats(t, n);
	check_swap();
	return kg_test_done("libcamera-formats");
#endif
}
