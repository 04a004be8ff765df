/* proc_label_warnings: what an object's labels do not know, as process.json holds it.
 * An object whose regions table has an unknown region, a region decided otherwise than
 * the class its pixels hold, and a compound class resolved to a member (not a change),
 * with a large share of unknown pixels: one warning of each kind, naming the regions;
 * then an object whose labels hold everything (a share of unknown pixels below the
 * threshold, a mostly-background frame below 99 %): none; then a frame of 99.5 %
 * background: the background warning. */
#include <string.h>

#include "kg_test.h"
#include "pipeline_private.h"

static json_t *object(double unknown, double background, json_t *table)
{
	return json_pack("{s:f,s:f,s:f,s:{s:o}}", "unknown_fraction", unknown,
	                 "background_fraction", background, "unclassified_fraction", 0.0,
	                 "regions", "table", table);
}

static json_t *region(int id, int pixels, const char *cls, const char *label,
                      const char *pixel_class)
{
	return json_pack("{s:i,s:i,s:s,s:s,s:s}", "region", id, "pixels", pixels, "class", cls,
	                 "label", label, "pixel_class", pixel_class);
}

/* how many warnings contain every one of the (NULL-terminated) strings */
static int count(const json_t *w, const char *a, const char *b, const char *c)
{
	int n = 0;
	size_t i;
	const json_t *s;
	json_array_foreach(w, i, s)
	{
		const char *t = json_string_value(s);
		if (t && strstr(t, a) && (!b || strstr(t, b)) && (!c || strstr(t, c)))
			n++;
	}
	return n;
}

static void print(const char *what, const json_t *w)
{
	size_t i;
	const json_t *s;
	printf("%s: %zu warning(s)\n", what, json_array_size(w));
	json_array_foreach(w, i, s)
		printf("  %s\n", json_string_value(s));
}

int main(void)
{
	json_t *t = json_array();
	json_array_append_new(t, region(1, 1422, "gold", "gold", "gold"));
	json_array_append_new(t, region(2, 1376, "silver", "unknown", "silver"));
	json_array_append_new(t, region(3, 1414, "a|b", "a|b", "shibuichi-jo"));
	json_array_append_new(t, region(4, 1440, "copper|shakudo", "copper", "copper|shakudo"));
	json_t *o = object(0.04, 0.9, t); /* 40 % of the object's pixels unknown */
	json_t *w = proc_label_warnings("object-0001", o);
	print("mixed", w);
	CHECK(w && json_array_size(w) == 3, "3 warnings, got %zu", w ? json_array_size(w) : 0);
	CHECK(count(w, "object-0001", "1 region ", "decided unknown") == 1 &&
	          count(w, "2 (1376 px, pixels silver)", NULL, NULL) == 1,
	      "the unknown region, numbered, with its pixels' class");
	CHECK(count(w, "decided otherwise", "3 (1414 px): pixels shibuichi-jo, region a|b",
	            NULL) == 1,
	      "the region decided otherwise than its pixels");
	CHECK(count(w, "region 4", NULL, NULL) == 0 && count(w, "4 (1440", NULL, NULL) == 0,
	      "a compound class resolved to its member is not a change");
	CHECK(count(w, "40.0 % of the object's pixels are unknown", NULL, NULL) == 1,
	      "the share of unknown pixels among the object's");
	CHECK(count(w, "background", "covers little", NULL) == 0, "90 %% background: no warning");
	json_decref(w);
	json_decref(o);

	t = json_array();
	json_array_append_new(t, region(1, 1422, "gold", "gold", "gold"));
	o = object(0.007, 0.963, t); /* 19 % of the object's pixels unknown */
	w = proc_label_warnings("object-0001", o);
	print("clean", w);
	CHECK(w && json_array_size(w) == 0, "no warning, got %zu", w ? json_array_size(w) : 0);
	json_decref(w);
	json_decref(o);

	o = object(0.0, 0.995, json_array());
	w = proc_label_warnings("object-0002", o);
	print("background", w);
	CHECK(w && json_array_size(w) == 1 &&
	          count(w, "object-0002", "99.5 % of the pixels are background", NULL) == 1,
	      "the background share");
	json_decref(w);
	json_decref(o);
	return kg_test_done("label-warnings");
}
