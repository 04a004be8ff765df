/* make_dng: a linear image (kogei sim chart / sim image output: float RGB TIFF, or a
 * 1-channel mosaic) photographed as a camera writes a raw file: mosaicked with a CFA,
 * scaled to the raw range above a black level, optionally with shot noise, written as
 * an uncompressed DNG with the shooting metadata (dng.h). The tests' stand-in for a
 * DSLR's raw files.
 *
 * usage: make_dng IN OUT.dng [--cfa RGGB] [--black B|B0,B1,B2,B3] [--white W]
 *        [--scale F] [--noise FULLWELL:SEED] [--exposure S] [--iso I] [--fnumber F]
 *        [--focal MM] [--make M] [--model X] [--serial S] [--lens L] [--linear-raw]
 *        [--saturate DN]
 * raw = black + round(value * scale * (white - black)), clipped to 0..65535 (to DN
 * with --saturate: a sensor that stops short of the white level; the samples held
 * there are counted on standard output, "saturated N of M samples, P pixels"); with
 * noise, value * scale * FULLWELL electrons are drawn from a Poisson distribution. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dng.h"
#include "image.h"
#include "rng.h"

static int colour_of(char c)
{
	return c == 'R' ? 0 : c == 'G' ? 1 : 2;
}

int main(int argc, char **argv)
{
	if (argc < 3) {
		fprintf(stderr, "usage: make_dng IN OUT.dng [options] (see the source)\n");
		return 2;
	}
	test_dng d = {.cfa = "RGGB", .black = {256, 256, 256, 256}, .black_dim = 1, .white = 4095};
	double scale = 1, fullwell = 0, saturate = 65535;
	unsigned long long seed = 1;
	for (int i = 3; i + 1 < argc || (i < argc && !strcmp(argv[i], "--linear-raw")); i += 2) {
		const char *k = argv[i], *v = i + 1 < argc ? argv[i + 1] : "";
		if (!strcmp(k, "--linear-raw")) {
			d.linear_raw = 1;
			i--;
		} else if (!strcmp(k, "--cfa"))
			d.cfa = v;
		else if (!strcmp(k, "--black")) {
			int n = sscanf(v, "%lf,%lf,%lf,%lf", &d.black[0], &d.black[1], &d.black[2],
			               &d.black[3]);
			d.black_dim = n == 4 ? 2 : 1;
			if (n == 1)
				d.black[1] = d.black[2] = d.black[3] = d.black[0];
		} else if (!strcmp(k, "--white"))
			d.white = atof(v);
		else if (!strcmp(k, "--saturate"))
			saturate = atof(v);
		else if (!strcmp(k, "--scale"))
			scale = atof(v);
		else if (!strcmp(k, "--noise"))
			sscanf(v, "%lf:%llu", &fullwell, &seed);
		else if (!strcmp(k, "--exposure"))
			d.exposure_s = atof(v);
		else if (!strcmp(k, "--iso"))
			d.iso = atof(v);
		else if (!strcmp(k, "--fnumber"))
			d.fnumber = atof(v);
		else if (!strcmp(k, "--focal"))
			d.focal_mm = atof(v);
		else if (!strcmp(k, "--make"))
			d.make = v;
		else if (!strcmp(k, "--model"))
			d.model = v;
		else if (!strcmp(k, "--serial"))
			d.serial = v;
		else if (!strcmp(k, "--lens"))
			d.lens = v;
		else {
			fprintf(stderr, "make_dng: unknown option %s\n", k);
			return 2;
		}
	}
	kg_image *img = NULL;
	kg_err err = {{0}};
	if (kg_image_read(argv[1], &img, &err)) {
		fprintf(stderr, "make_dng: %s\n", err.msg);
		return 1;
	}
	int spp = d.linear_raw ? 3 : 1;
	if (d.linear_raw && img->channels != 3) {
		fprintf(stderr, "make_dng: --linear-raw needs an RGB image\n");
		return 1;
	}
	size_t n = (size_t)img->width * (size_t)img->height;
	uint16_t *raw = malloc(n * (size_t)spp * sizeof(*raw));
	if (!raw)
		return 1;
	kg_rng rng;
	kg_rng_seed(&rng, seed);
	long nsat = 0;
	for (int y = 0; y < img->height; y++)
		for (int x = 0; x < img->width; x++)
			for (int s = 0; s < spp; s++) {
				size_t i = (size_t)y * (size_t)img->width + (size_t)x;
				int site = (y & 1) * 2 + (x & 1);
				int ch = d.linear_raw ? s : img->channels == 3 ? colour_of(d.cfa[site]) : 0;
				double v = img->data[i * (size_t)img->channels + (size_t)ch] * scale;
				if (!(v > 0))
					v = 0;
				if (fullwell > 0)
					v = kg_rng_poisson(&rng, v * fullwell) / fullwell;
				double b = d.black_dim == 2 ? d.black[site] : d.black[0];
				double dn = b + round(v * (d.white - b));
				if (dn >= saturate) {
					dn = saturate;
					nsat++;
				}
				raw[i * (size_t)spp + (size_t)s] = (uint16_t)(dn < 0 ? 0 : dn > 65535 ? 65535 : dn);
			}
	if (saturate < 65535)
		printf("saturated %ld of %zu samples\n", nsat, n * (size_t)spp);
	d.width = img->width;
	d.height = img->height;
	d.data = raw;
	char msg[512];
	int ret = test_dng_write(argv[2], &d, msg, sizeof(msg));
	if (ret)
		fprintf(stderr, "make_dng: %s\n", msg);
	free(raw);
	kg_image_free(&img);
	return ret ? 1 : 0;
}
