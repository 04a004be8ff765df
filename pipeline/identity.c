/* kogei process, each object's identity: its record (the run's --meta overlaid by the
 * object capture's own "meta", the capture's winning), the session and object names,
 * when it was captured, the calibration's held-out colour error and the pixels per mm
 * of the chart's plane; written into master.tif (TIFF tags and an XMP packet),
 * cube.hdr's description, labels.json and object.glb (docs/formats.md, "Identity of
 * an object's files"). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_config.h"
#include "pipeline_private.h"

/* The record: the run's --meta, the capture's over it, in display order
 * (kg_meta_ordered_keys). */
static json_t *record_of(const proc *p, const proc_capture *c)
{
	json_t *all = json_object(), *out = json_object();
	if (!all || !out) {
		json_decref(all);
		json_decref(out);
		return NULL;
	}
	if (json_is_object(p->o->meta))
		json_object_update(all, (json_t *)p->o->meta);
	const json_t *own = json_object_get(c->j, "meta");
	if (json_is_object(own))
		json_object_update(all, (json_t *)own);
	const char *keys[KG_META_MAX_KEYS * 2];
	int n = kg_meta_ordered_keys(all, keys, KG_META_MAX_KEYS * 2);
	for (int i = 0; i < n; i++)
		json_object_set(out, keys[i], json_object_get(all, keys[i]));
	json_decref(all);
	return out;
}

/* The colour error the calibration reaches on patches it was not fitted to, as the
 * report grades it: a verification capture's (--verify) where there is one, else
 * leave-one-out; null when neither was measured. */
static json_t *colour_of(const proc *p)
{
	const json_t *patches = json_object_get(p->calibration, "patches");
	size_t n = json_array_size(patches);
	if (!n)
		return json_null();
	const char *key = "de00_d50_heldout", *basis = "leave-one-out";
	for (size_t i = 0; i < n; i++)
		if (json_is_number(json_object_get(json_array_get(patches, i), "de00_d50_verify"))) {
			key = "de00_d50_verify";
			basis = "verification capture";
		}
	double *v = malloc(n * sizeof(double));
	if (!v)
		return NULL;
	for (size_t i = 0; i < n; i++) {
		const json_t *e = json_object_get(json_array_get(patches, i), key);
		v[i] = json_is_number(e) ? json_number_value(e) : NAN;
	}
	kg_de_summary s;
	kg_err scratch;
	int ok = kg_de_summarise(v, (int)n, &s, &scratch) == 0 && s.n > 0;
	free(v);
	if (!ok)
		return json_null();
	return json_pack("{s:f, s:f, s:f, s:i, s:s, s:s}", "de00_mean", s.mean, "de00_p90", s.p90,
	                 "de00_max", s.max, "patches", s.n, "basis", basis, "illuminant", "D50");
}

/* Pixels per mm on the chart's plane at the chart's centre: the square root of the
 * area scale of the chart's homography (layout mm to the chart capture's pixels)
 * there. Known only when the layout is in mm and the object capture has the chart
 * capture's frame; *why says otherwise. */
static double pixels_per_mm(const proc *p, const proc_capture *c, char *why, size_t size)
{
	const kg_chart_layout *l = p->layout;
	const double *H = p->chart_H;
	if (!l) {
		snprintf(why, size, "no chart layout");
		return NAN;
	}
	if (l->template_units) {
		snprintf(why, size, "the layout %s is in template units, not mm", l->name);
		return NAN;
	}
	if (c->width != p->chart_width || c->height != p->chart_height) {
		snprintf(why, size, "capture %s is %ldx%ld pixels, the chart capture %s %dx%d",
		         c->name, c->width, c->height, p->chart->name, p->chart_width,
		         p->chart_height);
		return NAN;
	}
	const double *a = l->chart_area_mm;
	double x = a[2] > 0 ? a[0] + a[2] / 2 : l->width_mm / 2;
	double y = a[3] > 0 ? a[1] + a[3] / 2 : l->height_mm / 2;
	double nu = H[0] * x + H[1] * y + H[2], nv = H[3] * x + H[4] * y + H[5];
	double w = H[6] * x + H[7] * y + H[8];
	double w2 = w * w;
	double j00 = (H[0] * w - nu * H[6]) / w2, j01 = (H[1] * w - nu * H[7]) / w2;
	double j10 = (H[3] * w - nv * H[6]) / w2, j11 = (H[4] * w - nv * H[7]) / w2;
	double s = sqrt(fabs(j00 * j11 - j01 * j10));
	if (!isfinite(s) || !(s > 0)) {
		snprintf(why, size, "the chart's homography is degenerate");
		return NAN;
	}
	snprintf(why, size, "the chart capture %s: layout %s at its centre", p->chart->name,
	         l->name);
	return s;
}

static const char *base_name(const char *path)
{
	const char *s = path ? strrchr(path, '/') : NULL;
	return s && s[1] ? s + 1 : path ? path : "";
}

json_t *proc_identity(const proc *p, const proc_capture *c)
{
	char why[512];
	double ppmm = pixels_per_mm(p, c, why, sizeof(why));
	const json_t *sid = json_object_get(p->manifest, "id");
	const json_t *started = json_object_get(c->j, "started");
	json_t *record = record_of(p, c), *colour = colour_of(p);
	if (!record || !colour) {
		json_decref(record);
		json_decref(colour);
		return NULL;
	}
	return json_pack("{s:s, s:s, s:O, s:O, s:o, s:o, s:o, s:s}", "object", c->name,
	                 "session", base_name(p->session_abs ? p->session_abs : p->o->session),
	                 "session_id", json_is_string(sid) ? sid : json_null(), "captured",
	                 json_is_string(started) ? started : json_null(), "record", record,
	                 "colour_accuracy", colour, "pixels_per_mm",
	                 isfinite(ppmm) ? json_real(ppmm) : json_null(), "pixels_per_mm_source",
	                 isfinite(ppmm) ? why : "not known");
}

static const char *rec(const json_t *id, const char *key)
{
	return json_string_value(json_object_get(json_object_get(id, "record"), key));
}

/* ---- cube.hdr: the description ------------------------------------------------- */

int proc_identity_envi(const json_t *id, const char *first, char **out, kg_err *err)
{
	size_t len;
	FILE *f = open_memstream(out, &len);
	if (!f)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	fputs(first, f);
	static const char *const text[] = {"object", "session", "session_id", "captured"};
	for (size_t i = 0; i < sizeof(text) / sizeof(text[0]); i++) {
		const char *v = json_string_value(json_object_get(id, text[i]));
		if (v) {
			fprintf(f, "\n%s: ", text[i]);
			kg_envi_put_quoted(f, v);
		}
	}
	const char *k;
	json_t *v;
	json_object_foreach(json_object_get(id, "record"), k, v)
	{
		fprintf(f, "\nrecord.%s: ", k);
		kg_envi_put_quoted(f, json_string_value(v));
	}
	const json_t *col = json_object_get(id, "colour_accuracy");
	if (json_is_object(col)) {
		fprintf(f, "\ncolour_accuracy.de00_mean: %.4f\ncolour_accuracy.de00_max: %.4f\n"
		        "colour_accuracy.patches: %d\ncolour_accuracy.basis: ",
		        json_number_value(json_object_get(col, "de00_mean")),
		        json_number_value(json_object_get(col, "de00_max")),
		        (int)json_integer_value(json_object_get(col, "patches")));
		kg_envi_put_quoted(f, json_string_value(json_object_get(col, "basis")));
	}
	const json_t *ppmm = json_object_get(id, "pixels_per_mm");
	if (json_is_number(ppmm))
		fprintf(f, "\npixels_per_mm: %.4f", json_number_value(ppmm));
	if (fclose(f) != 0) {
		free(*out);
		*out = NULL;
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	return 0;
}

/* ---- master.tif: the XMP packet and the TIFF tags -------------------------------- */

#define XMP_NS_KOGEI "urn:kogei:xmp:1.0:"

static void xmp_simple(FILE *f, const char *tag, const char *v)
{
	if (!v)
		return;
	fprintf(f, "   <%s>", tag);
	kg_xml_put(f, v);
	fprintf(f, "</%s>\n", tag);
}

/* An array of one item: rdf:Alt (language alternative, x-default), rdf:Seq. */
static void xmp_one(FILE *f, const char *tag, const char *kind, const char *v)
{
	if (!v)
		return;
	fprintf(f, "   <%s>\n    <rdf:%s>\n     <rdf:li%s>", tag, kind,
	        strcmp(kind, "Alt") ? "" : " xml:lang=\"x-default\"");
	kg_xml_put(f, v);
	fprintf(f, "</rdf:li>\n    </rdf:%s>\n   </%s>\n", kind, tag);
}

static void xmp_number(FILE *f, const char *tag, const json_t *v, const char *fmt)
{
	char buf[64];
	if (!json_is_number(v))
		return;
	if (json_is_integer(v))
		snprintf(buf, sizeof(buf), "%lld", (long long)json_integer_value(v));
	else
		snprintf(buf, sizeof(buf), fmt, json_number_value(v));
	xmp_simple(f, tag, buf);
}

/* n digits at *s, advanced past them; -1 when they are not there. */
static int digits(const char **s, int n)
{
	int v = 0;
	for (int i = 0; i < n; i++, (*s)++) {
		if (**s < '0' || **s > '9')
			return -1;
		v = 10 * v + (**s - '0');
	}
	return v;
}

/* 1 when s is an XMP Date (XMP Part 1, 8.2.1.1; ISO 8601 as W3C profiles it): YYYY,
 * YYYY-MM, YYYY-MM-DD, and those with Thh:mm, Thh:mm:ss or Thh:mm:ss.s... and a zone
 * (Z, +hh:mm, -hh:mm). */
static int xmp_date_ok(const char *s)
{
	if (!s || digits(&s, 4) < 0)
		return 0;
	if (!*s)
		return 1;
	int v;
	if (*s++ != '-' || (v = digits(&s, 2)) < 1 || v > 12)
		return 0;
	if (!*s)
		return 1;
	if (*s++ != '-' || (v = digits(&s, 2)) < 1 || v > 31)
		return 0;
	if (!*s)
		return 1;
	if (*s++ != 'T' || (v = digits(&s, 2)) < 0 || v > 23 || *s++ != ':' ||
	    (v = digits(&s, 2)) < 0 || v > 59)
		return 0;
	if (*s == ':') {
		s++;
		if ((v = digits(&s, 2)) < 0 || v > 60)
			return 0;
		if (*s == '.') {
			s++;
			if (*s < '0' || *s > '9')
				return 0;
			while (*s >= '0' && *s <= '9')
				s++;
		}
	}
	if (*s == 'Z')
		return s[1] == 0;
	if (*s != '+' && *s != '-')
		return 0;
	s++;
	return (v = digits(&s, 2)) >= 0 && v <= 23 && *s++ == ':' && (v = digits(&s, 2)) >= 0 &&
	       v <= 59 && !*s;
}

const char *proc_identity_description(const json_t *id)
{
	return rec(id, "description") ? rec(id, "description") : rec(id, "title");
}

int proc_identity_xmp(const json_t *id, char **out, size_t *len, kg_err *err)
{
	FILE *f = open_memstream(out, len);
	if (!f)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	/* the packet wrapper (XMP Part 1, 7.3): the begin attribute holds U+FEFF */
	fputs("<?xpacket begin=\"\xef\xbb\xbf\" id=\"W5M0MpCehiHzreSzNTczkc9d\"?>\n"
	      "<x:xmpmeta xmlns:x=\"adobe:ns:meta/\" x:xmptk=\"kogei " KG_VERSION "\">\n"
	      " <rdf:RDF xmlns:rdf=\"http://www.w3.org/1999/02/22-rdf-syntax-ns#\">\n"
	      "  <rdf:Description rdf:about=\"\"\n"
	      "    xmlns:dc=\"http://purl.org/dc/elements/1.1/\"\n"
	      "    xmlns:xmp=\"http://ns.adobe.com/xap/1.0/\"\n"
	      "    xmlns:kogei=\"" XMP_NS_KOGEI "\">\n", f);
	xmp_simple(f, "dc:identifier", rec(id, "accession"));
	xmp_one(f, "dc:title", "Alt", rec(id, "title"));
	xmp_one(f, "dc:creator", "Seq", rec(id, "operator"));
	/* dc:date is an XMP Date: a date in other words ("c. 1650") is in kogei:Record */
	if (xmp_date_ok(rec(id, "date")))
		xmp_one(f, "dc:date", "Seq", rec(id, "date"));
	xmp_one(f, "dc:rights", "Alt", rec(id, "rights"));
	xmp_one(f, "dc:description", "Alt", proc_identity_description(id));
	xmp_simple(f, "dc:format", "image/tiff");
	xmp_simple(f, "xmp:CreatorTool", "kogei " KG_VERSION);
	xmp_simple(f, "xmp:CreateDate", json_string_value(json_object_get(id, "captured")));
	xmp_simple(f, "kogei:Object", json_string_value(json_object_get(id, "object")));
	xmp_simple(f, "kogei:Session", json_string_value(json_object_get(id, "session")));
	xmp_simple(f, "kogei:SessionID", json_string_value(json_object_get(id, "session_id")));
	const json_t *col = json_object_get(id, "colour_accuracy");
	if (json_is_object(col)) {
		xmp_number(f, "kogei:HeldOutDE00Mean", json_object_get(col, "de00_mean"), "%.4f");
		xmp_number(f, "kogei:HeldOutDE00P90", json_object_get(col, "de00_p90"), "%.4f");
		xmp_number(f, "kogei:HeldOutDE00Max", json_object_get(col, "de00_max"), "%.4f");
		xmp_number(f, "kogei:HeldOutPatches", json_object_get(col, "patches"), "%.0f");
		xmp_simple(f, "kogei:HeldOutBasis", json_string_value(json_object_get(col, "basis")));
	}
	xmp_number(f, "kogei:PixelsPerMM", json_object_get(id, "pixels_per_mm"), "%.4f");
	xmp_simple(f, "kogei:PixelsPerMMSource",
	           json_string_value(json_object_get(id, "pixels_per_mm_source")));
	/* the whole record, every key as given (a key need not be an XML name) */
	const json_t *r = json_object_get(id, "record");
	if (json_object_size(r)) {
		fputs("   <kogei:Record>\n    <rdf:Bag>\n", f);
		const char *k;
		json_t *v;
		json_object_foreach((json_t *)r, k, v)
		{
			fputs("     <rdf:li rdf:parseType=\"Resource\">\n      <kogei:Key>", f);
			kg_xml_put(f, k);
			fputs("</kogei:Key>\n      <kogei:Value>", f);
			kg_xml_put(f, json_string_value(v));
			fputs("</kogei:Value>\n     </rdf:li>\n", f);
		}
		fputs("    </rdf:Bag>\n   </kogei:Record>\n", f);
	}
	fputs("  </rdf:Description>\n </rdf:RDF>\n</x:xmpmeta>\n", f);
	/* padding, so that an editor can grow the packet in place (XMP Part 3, 2 KB) */
	for (int i = 0; i < 20; i++)
		fprintf(f, "%99s\n", "");
	fputs("<?xpacket end=\"w\"?>", f);
	if (fclose(f) != 0) {
		free(*out);
		*out = NULL;
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	return 0;
}

void proc_identity_tiff(const json_t *id, const char *xmp, size_t xmp_len, char datetime[20],
                        kg_tiff_identity *t)
{
	memset(t, 0, sizeof(*t));
	t->description = proc_identity_description(id);
	t->artist = rec(id, "operator");
	t->copyright = rec(id, "rights");
	t->xmp = xmp;
	t->xmp_len = xmp_len;
	const json_t *ppmm = json_object_get(id, "pixels_per_mm");
	t->pixels_per_mm = json_is_number(ppmm) ? json_number_value(ppmm) : 0;
	/* DateTime: when the capture started, "2026-12-01T20:00:00.000Z" as TIFF writes
	 * it (UTC) */
	const char *s = json_string_value(json_object_get(id, "captured"));
	int Y, M, D, h, m, sec;
	if (s && sscanf(s, "%4d-%2d-%2dT%2d:%2d:%2d", &Y, &M, &D, &h, &m, &sec) == 6 &&
	    Y >= 0 && Y <= 9999 && M >= 1 && M <= 12 && D >= 1 && D <= 31 && h >= 0 && h < 24 &&
	    m >= 0 && m < 60 && sec >= 0 && sec <= 60) {
		snprintf(datetime, 20, "%04d:%02d:%02d %02d:%02d:%02d", Y, M, D, h, m, sec);
		t->datetime = datetime;
	}
}
