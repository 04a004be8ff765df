/* IEEE binary16 conversion: round trips, rounding on the edge values (ties,
 * subnormals, the largest finite value, overflow, Inf, NaN), and agreement bit for
 * bit with the CPU's own F16C conversion, an oracle from outside the project,
 * over a sweep of float bit patterns. */
#include <stdint.h>
#include <string.h>

#include "kg_estimate.h"
#include "kg_test.h"

static float from_bits(uint32_t u)
{
	float f;
	memcpy(&f, &u, sizeof(f));
	return f;
}

static uint32_t to_bits(float f)
{
	uint32_t u;
	memcpy(&u, &f, sizeof(u));
	return u;
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <cpuid.h>
#include <immintrin.h>

__attribute__((target("f16c"))) static uint16_t hw_f16(float f)
{
	return (uint16_t)_mm_extract_epi16(_mm_cvtps_ph(_mm_set_ss(f), _MM_FROUND_TO_NEAREST_INT), 0);
}

static int compare_with_f16c(void)
{
	unsigned a, b, c, d;
	if (!__get_cpuid(1, &a, &b, &c, &d) || !(c & bit_F16C)) {
		printf("no F16C on this CPU: hardware comparison skipped\n");
		return 0;
	}
	uint64_t n = 0, bad = 0;
	/* every 251st bit pattern, plus every pattern whose exponent is in or near the
	 * half range with the low mantissa bits that decide rounding varied */
	for (uint64_t u = 0; u <= 0xffffffffu; u += 251, n++)
		if (hw_f16(from_bits((uint32_t)u)) != kg_f16_from_f32(from_bits((uint32_t)u)))
			bad++;
	for (uint32_t e = 97; e <= 144; e++)
		for (uint32_t m = 0; m < (1u << 23); m += 4093)
			for (uint32_t low = 0; low < 4; low++)
				for (uint32_t sign = 0; sign < 2; sign++) {
					uint32_t u = sign << 31 | e << 23 | ((m & ~0x1fffu) | (0x1000u - 2 + low));
					n++;
					if (hw_f16(from_bits(u)) != kg_f16_from_f32(from_bits(u))) {
						if (bad < 5)
							fprintf(stderr, "0x%08x: F16C 0x%04x, ours 0x%04x\n", u,
							        hw_f16(from_bits(u)), kg_f16_from_f32(from_bits(u)));
						bad++;
					}
				}
	CHECK(bad == 0, "%llu of %llu conversions differ from F16C", (unsigned long long)bad,
	      (unsigned long long)n);
	printf("%llu conversions compared with F16C\n", (unsigned long long)n);
	return 1;
}
#else
static int compare_with_f16c(void) { return 0; }
#endif

int main(void)
{
	/* every half survives half -> float -> half; NaNs come back quiet */
	for (uint32_t h = 0; h < 65536; h++) {
		float f = kg_f32_from_f16((uint16_t)h);
		uint16_t back = kg_f16_from_f32(f);
		int nan = (h & 0x7c00) == 0x7c00 && (h & 0x3ff);
		if (nan)
			CHECK(isnan(f) && back == (h | 0x200), "NaN 0x%04x -> 0x%04x", h, back);
		else
			CHECK(back == h, "0x%04x -> %g -> 0x%04x", h, (double)f, back);
	}

	const struct {
		float f;
		uint16_t h;
		const char *what;
	} cases[] = {
	    {0.0f, 0x0000, "zero"},
	    {-0.0f, 0x8000, "negative zero"},
	    {1.0f, 0x3c00, "one"},
	    {-2.0f, 0xc000, "minus two"},
	    {65504.0f, 0x7bff, "largest finite"},
	    {65519.99f, 0x7bff, "just below the overflow tie"},
	    {65520.0f, 0x7c00, "overflow tie rounds to even = Inf"},
	    {1e10f, 0x7c00, "overflow"},
	    {-1e10f, 0xfc00, "negative overflow"},
	    {INFINITY, 0x7c00, "Inf"},
	    {-INFINITY, 0xfc00, "-Inf"},
	    {0x1p-14f, 0x0400, "smallest normal"},
	    {0x1p-24f, 0x0001, "smallest subnormal"},
	    {1023 * 0x1p-24f, 0x03ff, "largest subnormal"},
	    {0x1p-25f, 0x0000, "half the smallest subnormal: tie to even 0"},
	    {0x1.8p-25f, 0x0001, "above the tie"},
	    {3 * 0x1p-25f, 0x0002, "1.5 subnormal units: tie to even 2"},
	    {5 * 0x1p-25f, 0x0002, "2.5 subnormal units: tie to even 2"},
	    {0x1.ff8p-15f, 0x03ff, "largest subnormal, as a float"},
	    {0x1.ffcp-15f, 0x0400, "tie above the largest subnormal: even = smallest normal"},
	    {1.0f + 0x1p-11f, 0x3c00, "tie to even mantissa 0"},
	    {1.0f + 3 * 0x1p-11f, 0x3c02, "tie to even mantissa 2"},
	    {1.0f + 0x1p-11f + 0x1p-20f, 0x3c01, "just above a tie"},
	    {1e-40f, 0x0000, "float subnormal"},
	    {-1e-40f, 0x8000, "negative float subnormal"},
	};
	for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
		uint16_t h = kg_f16_from_f32(cases[i].f);
		CHECK(h == cases[i].h, "%s: %a -> 0x%04x, expected 0x%04x", cases[i].what,
		      (double)cases[i].f, h, cases[i].h);
	}
	CHECK(kg_f16_from_f32(NAN) == 0x7e00, "NaN -> 0x%04x", kg_f16_from_f32(NAN));
	CHECK(kg_f16_from_f32(from_bits(0x7f800001)) == 0x7e00, "signalling NaN is quietened");
	CHECK(kg_f16_from_f32(from_bits(0xffc02000)) == 0xfe01, "NaN keeps sign and upper payload");
	CHECK(to_bits(kg_f32_from_f16(0x0001)) == to_bits(0x1p-24f), "subnormal back to float");
	CHECK(to_bits(kg_f32_from_f16(0x8000)) == 0x80000000u, "-0 back to float");
	CHECK(kg_f32_from_f16(0x7bff) == 65504.0f, "largest finite back to float");
	compare_with_f16c();
	return kg_test_done("f16 conversion");
}
