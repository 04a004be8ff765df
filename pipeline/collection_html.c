/* OUT/index.html: the collection as one table a conservator can sort (object, accession,
 * status, warnings, held-out colour difference, conformance grade, thumbnail, report),
 * self-contained: thumbnails inline, one inline script allowed by its sha256 in the
 * page's Content-Security-Policy and nothing else loaded. Every text from the record is
 * written through kg_html_put. */
#include <math.h>
#include <openssl/evp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "collection_private.h"

/* Clicking a column's header sorts the rows by its cells' data-v (numbers for a
 * data-type="num" column, empty last), again the other way. */
static const char sort_script[] =
	"(function(){var t=document.getElementById('collection'),b=t.tBodies[0];"
	"Array.prototype.forEach.call(t.tHead.rows[0].cells,function(h){"
	"var k=h.querySelector('button');if(!k)return;k.addEventListener('click',function(){"
	"var c=h.cellIndex,n=h.getAttribute('data-type')==='num',"
	"d=h.getAttribute('aria-sort')==='ascending'?-1:1,"
	"r=Array.prototype.slice.call(b.rows);"
	"Array.prototype.forEach.call(t.tHead.rows[0].cells,function(x){"
	"x.removeAttribute('aria-sort');});"
	"h.setAttribute('aria-sort',d>0?'ascending':'descending');"
	"r.sort(function(x,y){var p=x.cells[c].getAttribute('data-v'),"
	"q=y.cells[c].getAttribute('data-v');if(n){var e=p===''?1:0,f=q===''?1:0;"
	"if(e||f)return e-f;return (Number(p)-Number(q))*d;}return p.localeCompare(q)*d;});"
	"r.forEach(function(x){b.appendChild(x);});});});})();";

static const char style[] =
	"body{font:14px/1.4 system-ui,sans-serif;margin:1.5em;color:#222}"
	"table{border-collapse:collapse;width:100%}th,td{border-bottom:1px solid #ddd;"
	"padding:4px 8px;text-align:left;vertical-align:middle}"
	"th button{font:inherit;font-weight:bold;border:0;background:none;cursor:pointer;"
	"padding:0}th[aria-sort=ascending] button::after{content:' \\25B2'}"
	"th[aria-sort=descending] button::after{content:' \\25BC'}"
	"td.num{text-align:right;font-variant-numeric:tabular-nums}"
	".done{color:#1a7f37}.failed{color:#b42318;font-weight:bold}.pending{color:#8a6d00}"
	"img.thumb{max-width:128px;max-height:128px}.reason{font-size:12px;color:#b42318}"
	"@media print{th button::after{content:''}}";

static void put_base64(FILE *fp, const unsigned char *p, size_t len)
{
	static const char d[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
	size_t i = 0;
	for (; i + 3 <= len; i += 3) {
		uint32_t v = (uint32_t)p[i] << 16 | (uint32_t)p[i + 1] << 8 | p[i + 2];
		fputc(d[v >> 18], fp);
		fputc(d[v >> 12 & 63], fp);
		fputc(d[v >> 6 & 63], fp);
		fputc(d[v & 63], fp);
	}
	if (i < len) {
		uint32_t v = (uint32_t)p[i] << 16 | (i + 1 < len ? (uint32_t)p[i + 1] << 8 : 0);
		fputc(d[v >> 18], fp);
		fputc(d[v >> 12 & 63], fp);
		fputc(i + 1 < len ? d[v >> 6 & 63] : '=', fp);
		fputc('=', fp);
	}
}

/* <td data-v="V" class="cls">TEXT</td> */
static void cell(FILE *fp, const char *cls, const char *v, const char *text)
{
	fputs("<td data-v=\"", fp);
	kg_html_put(fp, v ? v : "");
	fputs("\"", fp);
	if (cls)
		fprintf(fp, " class=\"%s\"", cls);
	fputs(">", fp);
	kg_html_put(fp, text ? text : "");
	fputs("</td>", fp);
}

static void thumb_cell(FILE *fp, const char *out, const char *name, const char *capture)
{
	fputs("<td data-v=\"\">", fp);
	char *dir = coll_thumb_dir(out, name), *file = NULL;
	char *buf = NULL;
	size_t len = 0;
	if (dir && capture && kg_name_is_safe(capture, COLL_NAME_MAX) &&
	    asprintf(&file, "%s/%s.png", dir, capture) >= 0 &&
	    kg_read_file(file, &buf, &len, NULL) == 0) {
		kg_inputs_forget(file);
		fputs("<img class=\"thumb\" alt=\"", fp);
		kg_html_putf(fp, "%s / %s", name, capture);
		fputs("\" src=\"data:image/png;base64,", fp);
		put_base64(fp, (const unsigned char *)buf, len);
		fputs("\">", fp);
	}
	free(buf);
	free(file);
	free(dir);
	fputs("</td>", fp);
}

static void grade_text(const json_t *g, char *out, size_t size)
{
	const char *iso = json_string_value(json_object_get(g, "iso19264_1"));
	if (!iso) {
		snprintf(out, size, "not graded");
		return;
	}
	snprintf(out, size, "ISO 19264-1 %s, FADGI %lld star(s) (%lld of %lld measured)", iso,
	         (long long)json_integer_value(json_object_get(g, "fadgi_stars")),
	         (long long)json_integer_value(json_object_get(g, "measured")),
	         (long long)json_integer_value(json_object_get(g, "of")));
}

static void row(FILE *fp, const char *out, const json_t *entry, const json_t *obj)
{
	const char *name = json_string_value(json_object_get(entry, "name"));
	const char *status = json_string_value(json_object_get(entry, "status"));
	char v[128], text[256];
	fputs("<tr>", fp);
	cell(fp, NULL, name, name);
	const char *capture = obj ? json_string_value(json_object_get(obj, "name")) : NULL;
	cell(fp, NULL, capture ? capture : "", capture ? capture : "-");
	/* an entry without objects: the accession its row of the list gives */
	const char *acc = json_string_value(
		obj ? json_object_get(obj, "accession")
		    : json_object_get(json_object_get(entry, "meta"), "accession"));
	cell(fp, NULL, acc ? acc : "", acc ? acc : "-");
	/* status, with the reason of a failure */
	fprintf(fp, "<td data-v=\"%s\" class=\"%s\">", status, status);
	kg_html_put(fp, status);
	const char *reason = json_string_value(json_object_get(entry, "reason"));
	if (reason && !strcmp(status, "failed")) {
		fputs("\n<div class=\"reason\">", fp);
		kg_html_put(fp, reason);
		fputs("</div>", fp);
	}
	fputs("</td>", fp);
	/* warnings: how many, each in the cell's title */
	const json_t *w = obj ? json_object_get(obj, "warnings") : NULL;
	size_t nw = json_array_size(w), i;
	const json_t *x;
	if (obj)
		fprintf(fp, "<td class=\"num\" data-v=\"%zu\" title=\"", nw);
	else
		fputs("<td class=\"num\" data-v=\"\" title=\"", fp);
	json_array_foreach(w, i, x)
	{
		if (i)
			fputs("&#10;", fp);
		kg_html_put(fp, json_string_value(x) ? json_string_value(x) : "");
	}
	fputs("\">", fp);
	if (obj)
		fprintf(fp, "%zu", nw);
	else
		fputs("-", fp);
	fputs("</td>", fp);
	const json_t *de = obj ? json_object_get(obj, "de00_heldout") : NULL;
	double mean = json_number_value(json_object_get(de, "mean"));
	if (json_is_number(json_object_get(de, "mean")) && isfinite(mean)) {
		snprintf(v, sizeof(v), "%.6f", mean);
		snprintf(text, sizeof(text), "%.2f", mean);
		cell(fp, "num", v, text);
	} else {
		cell(fp, "num", "", "-");
	}
	const json_t *g = obj ? json_object_get(obj, "grade") : NULL;
	grade_text(g, text, sizeof(text));
	cell(fp, NULL, json_is_object(g) ? text : "", obj ? text : "-");
	thumb_cell(fp, out, name, capture);
	fputs("<td data-v=\"\">", fp);
	if (obj) {
		fputs("<a href=\"", fp);
		kg_html_putf(fp, "%s/report.html", name);
		fputs("\">report</a>", fp);
	} else {
		fputs("-", fp);
	}
	fputs("</td></tr>\n", fp);
}

int coll_html_write(const char *out, const json_t *record, kg_err *err)
{
	unsigned char md[EVP_MAX_MD_SIZE];
	unsigned int mdlen = 0;
	if (!EVP_Digest(sort_script, strlen(sort_script), md, &mdlen, EVP_sha256(), NULL))
		return kg_fail(err, KG_EIO, "sha256 of the page's script failed (OpenSSL)");
	char *path = kg_path_join(out, "index.html");
	kg_outfile f;
	int ret = path ? kg_outfile_open(&f, path, 0, err) : kg_fail(err, KG_ENOMEM, "out of memory");
	if (ret) {
		free(path);
		return ret;
	}
	FILE *fp = f.fp;
	fputs("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
	      "<meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; "
	      "img-src data:; style-src 'unsafe-inline'; script-src 'sha256-", fp);
	put_base64(fp, md, mdlen);
	fputs("'\">\n<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
	      "<title>Collection: ", fp);
	const char *list = json_string_value(json_object_get(record, "list"));
	kg_html_put(fp, list ? list : "");
	fprintf(fp, "</title>\n<style>%s</style>\n</head>\n<body>\n<h1>Collection</h1>\n<p>", style);
	const json_t *counts = json_object_get(record, "counts");
	kg_html_putf(fp, "%s: %lld entries, %lld done, %lld failed, %lld pending; engine %s; "
	             "written %s. Click a column's name to sort by it.", list ? list : "",
	             (long long)json_integer_value(json_object_get(counts, "entries")),
	             (long long)json_integer_value(json_object_get(counts, "done")),
	             (long long)json_integer_value(json_object_get(counts, "failed")),
	             (long long)json_integer_value(json_object_get(counts, "pending")),
	             json_string_value(json_object_get(record, "engine")),
	             json_string_value(json_object_get(record, "written")));
	fputs("</p>\n<table id=\"collection\">\n<thead><tr>"
	      "<th><button type=\"button\">Entry</button></th>"
	      "<th><button type=\"button\">Object</button></th>"
	      "<th><button type=\"button\">Accession</button></th>"
	      "<th><button type=\"button\">Status</button></th>"
	      "<th data-type=\"num\"><button type=\"button\">Warnings</button></th>"
	      "<th data-type=\"num\"><button type=\"button\">&Delta;E<sub>00</sub> held out"
	      "</button></th>"
	      "<th><button type=\"button\">Conformance</button></th>"
	      "<th>Thumbnail</th><th>Report</th></tr></thead>\n<tbody>\n", fp);
	size_t i, k;
	const json_t *e, *obj;
	json_array_foreach(json_object_get(record, "entries"), i, e)
	{
		const json_t *objs = json_object_get(e, "objects");
		if (!json_array_size(objs))
			row(fp, out, e, NULL);
		json_array_foreach(objs, k, obj)
			row(fp, out, e, obj);
	}
	fputs("</tbody>\n</table>\n<script>", fp);
	fputs(sort_script, fp);
	fputs("</script>\n</body>\n</html>\n", fp);
	ret = kg_outfile_commit(&f, err);
	free(path);
	return ret;
}
