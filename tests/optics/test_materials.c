/* Materials and the library: the default library loads and gives finite reflectances
 * in [0, 1] at every angle, alloys are composition-weighted sums, the full model never
 * reflects more than it receives, and malformed libraries fail naming file, entry and
 * field. */
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

#include "hemisphere.h"
#include "kg_optics.h"
#include "kg_test.h"
#include "tmpfiles.h"

static const char *const default_names[] = {
	"gold", "silver", "copper", "shakudo", "shibuichi-nami", "shibuichi-shiro",
	"shibuichi-jo", "shibuichi-nami-uchisanbu", "shibuichi-nami-sotosanbu", "urushi",
};

static int in_unit_interval(const kg_spectrum *s)
{
	for (int i = 0; i < KG_NBANDS; i++)
		if (!(s->v[i] >= 0.0 && s->v[i] <= 1.0))
			return 0;
	return 1;
}

static void reflectance_sweep(const kg_material *m)
{
	int bad = 0;
	for (int d = 0; d <= 1801; d++) {
		/* 0..90 deg in 0.05 deg steps, then pi/2 itself */
		double theta = d <= 1800 ? d * 0.05 * M_PI / 180 : M_PI_2;
		kg_spectrum r;
		kg_err e = {""};
		if (kg_material_reflectance(m, theta, &r, &e) != 0 || !in_unit_interval(&r)) {
			if (bad++ < 3)
				fprintf(stderr, "%s at %.2f deg: %s r400 %g\n", m->name, d * 0.05, e.msg,
				        r.v[0]);
		}
	}
	CHECK(bad == 0, "%s: %d angles gave an error or a reflectance outside [0, 1]",
	      m->name, bad);
}

typedef struct eval_ctx {
	const kg_material *m;
	const double *L;
	int bad;
} eval_ctx;

static const double N[3] = {0, 0, 1};

/* f_r (N.V) = eval / (N.L) * (N.V), every band */
static void eval_times_cos(const double V[3], double w, double *acc, void *p)
{
	eval_ctx *c = p;
	if (V[2] <= 0)
		return;
	kg_spectrum s;
	if (kg_material_eval(c->m, N, V, c->L, &s, NULL) != 0 || !kg_spectrum_isfinite(&s)) {
		c->bad++;
		return;
	}
	for (int b = 0; b < KG_NBANDS; b++) {
		if (s.v[b] < 0)
			c->bad++;
		acc[b] += w * s.v[b] / c->L[2] * V[2];
	}
}

/* Directional albedo of the full model at a few incidences, every band: <= 1. */
static double albedo_check(const kg_material *m)
{
	const double incid[] = {0, 60, 85};
	double worst = 0;
	for (int i = 0; i < 3; i++) {
		double L[3], R[3], a[KG_NBANDS];
		direction(incid[i] * M_PI / 180, 0, L);
		R[0] = -L[0];
		R[1] = -L[1];
		R[2] = L[2];
		eval_ctx c = {m, L, 0};
		integrate_around(R, 150, 90, KG_NBANDS, eval_times_cos, &c, a);
		CHECK(c.bad == 0, "%s: %d evaluations failed or were negative", m->name, c.bad);
		for (int b = 0; b < KG_NBANDS; b++) {
			CHECK(a[b] <= 1.0 + 2e-3, "%s at %g deg, %g nm: albedo %.5f > 1", m->name,
			      incid[i], kg_band_nm(b), a[b]);
			worst = fmax(worst, a[b]);
		}
	}
	return worst;
}

static void default_library(void)
{
	char path[4096];
	snprintf(path, sizeof(path), "%s/fixtures/materials/default.json", KG_SOURCE_ROOT);
	kg_material_library *lib = NULL;
	kg_err e = {""};
	int r = kg_material_library_load(path, &lib, &e);
	CHECK(r == 0, "%s", e.msg);
	if (r != 0)
		return;
	int n = kg_material_library_count(lib);
	CHECK(n == 10, "%d materials, expected 10", n);
	for (int i = 0; i < n && i < 10; i++) {
		const kg_material *m = kg_material_library_get(lib, i);
		CHECK(strcmp(m->name, default_names[i]) == 0, "entry %d is %s, expected %s", i,
		      m->name, default_names[i]);
		CHECK(kg_material_library_find(lib, default_names[i]) == m, "find %s",
		      default_names[i]);
		CHECK(kg_material_validate(m, &e) == 0, "%s", e.msg);
		/* every library material carries its prediction's own error (README.md) */
		CHECK(m->model_rsd[0] > 0 && m->model_rsd[1] > 0 && m->model_rsd[2] > 0 &&
		          m->model_rsd[0] < 0.2 && m->model_rsd[1] < 0.2 && m->model_rsd[2] < 0.2,
		      "%s: model_rsd %g %g %g, expected in (0, 0.2)", m->name, m->model_rsd[0],
		      m->model_rsd[1], m->model_rsd[2]);
		reflectance_sweep(m);
		kg_spectrum r0;
		kg_material_reflectance(m, 0, &r0, NULL);
		printf("%-26s R(0) at 450/550/650 nm: %.3f %.3f %.3f\n", m->name, r0.v[10],
		       r0.v[30], r0.v[50]);
	}
	CHECK(kg_material_library_find(lib, "bronze") == NULL, "no bronze in the library");
	CHECK(kg_material_library_get(lib, -1) == NULL && kg_material_library_get(lib, n) ==
	      NULL, "out-of-range index");

	/* eq. 3/4: the alloy is the composition-weighted sum of its metals */
	const kg_material *cu = kg_material_library_find(lib, "copper"),
	                  *au = kg_material_library_find(lib, "gold"),
	                  *ag = kg_material_library_find(lib, "silver"),
	                  *sk = kg_material_library_find(lib, "shakudo"),
	                  *sh = kg_material_library_find(lib, "shibuichi-shiro");
	for (double th = 0; th < 1.5; th += 0.3) {
		kg_spectrum rc, ra, rg, rs, rh;
		kg_material_reflectance(cu, th, &rc, NULL);
		kg_material_reflectance(au, th, &ra, NULL);
		kg_material_reflectance(ag, th, &rg, NULL);
		kg_material_reflectance(sk, th, &rs, NULL);
		kg_material_reflectance(sh, th, &rh, NULL);
		for (int b = 0; b < KG_NBANDS; b++) {
			CHECK_NEAR(rs.v[b], 0.96 * rc.v[b] + 0.04 * ra.v[b], 1e-15, "shakudo mix");
			CHECK_NEAR(rh.v[b], 0.594 * rg.v[b] + 0.396 * rc.v[b] + 0.010 * ra.v[b], 1e-15,
			           "shibuichi-shiro mix");
		}
	}
	/* dielectric: F + (1 - F) body at normal incidence, F = ((n - 1)/(n + 1))^2 */
	const kg_material *u = kg_material_library_find(lib, "urushi");
	kg_spectrum ru;
	kg_material_reflectance(u, 0, &ru, NULL);
	double f = 0.04; /* n = 1.5 */
	CHECK_NEAR(ru.v[0], f + (1 - f) * 0.020, 1e-12, "urushi R(0) at 400 nm");
	CHECK_NEAR(ru.v[60], f + (1 - f) * 0.050, 1e-12, "urushi R(0) at 700 nm");
	/* grazing: every material reflects (almost) everything */
	for (int i = 0; i < n; i++) {
		kg_spectrum rg90;
		kg_material_reflectance(kg_material_library_get(lib, i), M_PI_2, &rg90, NULL);
		CHECK(rg90.v[30] > 1 - 1e-12, "%s: R(90 deg) = %.17g",
		      kg_material_library_get(lib, i)->name, rg90.v[30]);
	}

	double worst = 0;
	for (int i = 0; i < n; i++)
		worst = fmax(worst, albedo_check(kg_material_library_get(lib, i)));
	printf("default library: largest directional albedo of the full model %.5f\n", worst);

	/* angles outside 0..pi/2 are refused, naming the material */
	kg_spectrum tmp;
	e.msg[0] = 0;
	CHECK(kg_material_reflectance(au, 1.6, &tmp, &e) == KG_EINVAL && strstr(e.msg, "gold"),
	      "theta > pi/2: %s", e.msg);
	double notunit[3] = {0, 0.5, 0.5};
	CHECK(kg_material_eval(au, N, notunit, N, &tmp, &e) == KG_EINVAL, "non-unit V");
	kg_material_library_free(&lib);
	CHECK(lib == NULL, "free nulls the pointer");
	kg_material_library_free(&lib);
}

/* Extreme materials built by hand: still within [0, 1]. */
static void extremes(void)
{
	kg_material m = {0};
	snprintf(m.name, sizeof(m.name), "white-lacquer");
	m.kind = KG_MATERIAL_DIELECTRIC;
	m.nk.n = kg_spectrum_const(3.0);
	m.body = kg_spectrum_const(1.0);
	m.roughness = 0.3;
	m.mirror_width = 0.02;
	m.gloss = 0.5;
	m.mirror = 0.5;
	kg_err e = {""};
	CHECK(kg_material_validate(&m, &e) == 0, "%s", e.msg);
	reflectance_sweep(&m);
	double a = albedo_check(&m);
	printf("dielectric n 3, body 1: largest albedo %.5f\n", a);

	kg_material p = m;
	snprintf(p.name, sizeof(p.name), "perfect-conductor");
	p.kind = KG_MATERIAL_METAL;
	p.nk.n = kg_spectrum_const(0.0);
	p.nk.k = kg_spectrum_const(50.0);
	p.roughness = 0.05;
	CHECK(kg_material_validate(&p, &e) == 0, "%s", e.msg);
	reflectance_sweep(&p);
	a = albedo_check(&p);
	printf("metal n 0, k 50: largest albedo %.5f\n", a);
}

static void validation(void)
{
	kg_material m = {0};
	snprintf(m.name, sizeof(m.name), "odd-alloy");
	m.kind = KG_MATERIAL_ALLOY;
	m.roughness = 0.1;
	m.mirror_width = 0.02;
	m.gloss = 0.8;
	m.mirror = 0.2;
	m.ncomponents = 2;
	kg_nk_rakic1998_ld("Cu", &m.component[0].nk, NULL);
	kg_nk_rakic1998_ld("Au", &m.component[1].nk, NULL);
	m.component[0].fraction = 0.95;
	m.component[1].fraction = 0.04;
	kg_err e = {""};
	CHECK(kg_material_validate(&m, &e) == KG_EINVAL && strstr(e.msg, "odd-alloy") &&
	      strstr(e.msg, "sum to 0.99"), "fractions summing to 0.99: %s", e.msg);
	kg_spectrum r;
	CHECK(kg_material_reflectance(&m, 0, &r, &e) == KG_EINVAL, "reflectance validates");
	m.component[0].fraction = 0.96 + 5e-7; /* within 1e-6 */
	CHECK(kg_material_validate(&m, &e) == 0, "%s", e.msg);
	/* and still no reflectance above 1 at grazing incidence */
	CHECK(kg_material_reflectance(&m, M_PI_2, &r, &e) == 0 && in_unit_interval(&r),
	      "fractions summing to 1 + 5e-7: R(90 deg) = %.17g", r.v[0]);
	m.component[0].fraction = 0.96 - 5e-7;
	reflectance_sweep(&m);
	m.component[0].fraction = 0.96 + 2e-6;
	CHECK(kg_material_validate(&m, &e) == KG_EINVAL, "1 + 2e-6 refused");
	m.component[0].fraction = 1.01;
	m.component[1].fraction = -0.01;
	CHECK(kg_material_validate(&m, &e) == KG_EINVAL && strstr(e.msg, "components[0]"),
	      "fraction > 1: %s", e.msg);
	m.component[0].fraction = 0.96;
	m.component[1].fraction = 0.04;
	m.ncomponents = 0;
	CHECK(kg_material_validate(&m, &e) == KG_EINVAL, "no components");
	m.ncomponents = 2;
	m.gloss = 0.9;
	CHECK(kg_material_validate(&m, &e) == KG_EINVAL && strstr(e.msg, "gloss"),
	      "gloss + mirror > 1: %s", e.msg);
	m.gloss = 0.8;
	m.roughness = 0;
	CHECK(kg_material_validate(&m, &e) == KG_EINVAL && strstr(e.msg, "roughness"),
	      "roughness 0: %s", e.msg);
	m.roughness = 0.1;
	m.component[1].nk.k.v[7] = NAN;
	CHECK(kg_material_validate(&m, &e) == KG_EINVAL && strstr(e.msg, "435 nm"),
	      "NaN k: %s", e.msg);

	kg_material d = {0};
	snprintf(d.name, sizeof(d.name), "glass");
	d.kind = KG_MATERIAL_DIELECTRIC;
	d.nk.n = kg_spectrum_const(1.5);
	d.body = kg_spectrum_const(1.2);
	d.roughness = d.mirror_width = 0.1;
	CHECK(kg_material_validate(&d, &e) == KG_EINVAL && strstr(e.msg, "body"),
	      "body > 1: %s", e.msg);
	d.body = kg_spectrum_const(0.5);
	d.nk.k.v[3] = 0.1;
	CHECK(kg_material_validate(&d, &e) == KG_EINVAL, "dielectric with k");
}

/* A library file whose loading must fail with a message containing each needle. */
static void bad_library(const char *json, const char *n1, const char *n2)
{
	const char *path = kg_tmpfile("lib/bad.json", json);
	kg_material_library *lib = NULL;
	kg_err e = {""};
	int r = kg_material_library_load(path, &lib, &e);
	CHECK(r < 0 && lib == NULL, "loaded, expected an error: %s", json);
	CHECK(strstr(e.msg, "bad.json") && strstr(e.msg, n1) && (!n2 || strstr(e.msg, n2)),
	      "message '%s' lacks 'bad.json', '%s' or '%s'", e.msg, n1, n2 ? n2 : "");
	kg_material_library_free(&lib);
}

#define HEAD "{\"format\": \"kogei-materials/1\", \"materials\": ["
#define CU "{\"name\": \"cu\", \"kind\": \"metal\", " \
	"\"nk\": {\"model\": \"rakic1998-ld\", \"element\": \"Cu\"}}"
#define AU "{\"name\": \"au\", \"kind\": \"metal\", " \
	"\"nk\": {\"model\": \"rakic1998-ld\", \"element\": \"Au\"}}"

static void library_files(void)
{
	char dir[1024];
	snprintf(dir, sizeof(dir), "%s/lib", kg_tmpdir);
	mkdir(dir, 0700);
	snprintf(dir, sizeof(dir), "%s/lib/tables", kg_tmpdir);
	mkdir(dir, 0700);

	bad_library(HEAD CU ", " AU ", {\"name\": \"alloy-x\", \"kind\": \"alloy\", "
	            "\"components\": [{\"material\": \"cu\", \"fraction\": 0.9}, "
	            "{\"material\": \"au\", \"fraction\": 0.05}]}]}",
	            "alloy-x", "sum to 0.95");
	bad_library(HEAD "{\"name\": \"a\", \"kind\": \"alloy\", \"components\": "
	            "[{\"material\": \"zinc\", \"fraction\": 1}]}]}", "'a'", "zinc");
	bad_library(HEAD "{\"name\": \"l\", \"kind\": \"dielectric\", \"n\": 1.5, \"body\": 0.1},"
	            " {\"name\": \"a\", \"kind\": \"alloy\", \"components\": "
	            "[{\"material\": \"l\", \"fraction\": 1}]}]}", "expected a metal", "'a'");
	bad_library(HEAD CU ", " CU "]}", "materials[1]", "already used");
	bad_library(HEAD "{\"name\": \"x\", \"kind\": \"plastic\"}]}", "'x'", "kind");
	bad_library(HEAD "{\"name\": \"cu\", \"kind\": \"metal\", \"rougness\": 0.1, "
	            "\"nk\": {\"model\": \"rakic1998-ld\", \"element\": \"Cu\"}}]}",
	            "'cu'", "rougness");
	bad_library(HEAD "{\"name\": \"cu\", \"kind\": \"metal\"}]}", "'cu'", "nk");
	bad_library(HEAD "{\"name\": \"cu\", \"kind\": \"metal\", \"nk\": {\"model\": "
	            "\"drude\", \"element\": \"Cu\"}}]}", "'cu'", "drude");
	bad_library(HEAD "{\"name\": \"sn\", \"kind\": \"metal\", \"nk\": {\"model\": "
	            "\"rakic1998-ld\", \"element\": \"Sn\"}}]}", "'sn'", "Sn");
	bad_library(HEAD "{\"name\": \"cu\", \"kind\": \"metal\", \"nk\": \"missing.csv\"}]}",
	            "'cu'", "missing.csv");
	bad_library(HEAD "{\"name\": \"cu\", \"kind\": \"metal\", \"roughness\": \"smooth\", "
	            "\"nk\": {\"model\": \"rakic1998-ld\", \"element\": \"Cu\"}}]}", "'cu'",
	            "roughness");
	bad_library(HEAD "{\"name\": \"cu\", \"kind\": \"metal\", \"gloss\": 0.9, "
	            "\"nk\": {\"model\": \"rakic1998-ld\", \"element\": \"Cu\"}}]}", "'cu'",
	            "gloss");
	bad_library(HEAD "{\"name\": \"l\", \"kind\": \"dielectric\", \"n\": 1.5}]}", "'l'",
	            "body");
	bad_library(HEAD "{\"name\": \"l\", \"kind\": \"dielectric\", \"n\": 1.5, \"body\": "
	            "{\"wavelength_nm\": [400, 700], \"reflectance\": [0.1]}}]}", "'l'", "body");
	bad_library(HEAD "{\"name\": \"l\", \"kind\": \"dielectric\", \"n\": 1.5, \"body\": "
	            "{\"wavelength_nm\": [450, 700], \"reflectance\": [0.1, 0.2]}}]}", "'l'",
	            "450-700");
	bad_library(HEAD "{\"name\": \"l\", \"kind\": \"dielectric\", \"n\": 1.5, \"body\": "
	            "1.5}]}", "'l'", "body");
	bad_library(HEAD "]}", "materials", NULL);
	/* the prediction's own error */
	bad_library(HEAD "{\"name\": \"cu\", \"kind\": \"metal\", \"model_rsd\": [0.01, 0.02], "
	            "\"nk\": {\"model\": \"rakic1998-ld\", \"element\": \"Cu\"}}]}", "'cu'",
	            "model_rsd");
	bad_library(HEAD "{\"name\": \"cu\", \"kind\": \"metal\", \"model_rsd\": [0.01, -1, 0], "
	            "\"nk\": {\"model\": \"rakic1998-ld\", \"element\": \"Cu\"}}]}", "'cu'",
	            "model_rsd[1]");
	/* coupon templates (kogei materials learn) */
#define CU_T(views) "{\"name\": \"cu\", \"kind\": \"metal\", " \
	"\"nk\": {\"model\": \"rakic1998-ld\", \"element\": \"Cu\"}, " \
	"\"template\": {\"reference\": \"\", \"views\": [" views "]}}]}"
#define VIEW(a, v) "{\"angle_deg\": " #a ", \"mean\": [0.5, 0.4, 0.3], \"cov\": [" #v \
	", 0, 0, 0, 1e-4, 0, 0, 0, 1e-4], \"pixels\": 500}"
	bad_library(HEAD CU_T(VIEW(30, 1e-4) ", " VIEW(10, 1e-4)), "'cu'", "template.views[1]");
	bad_library(HEAD CU_T(VIEW(30, -1e-4)), "'cu'", "variances >= 0");
	bad_library(HEAD CU_T(VIEW(95, 1e-4)), "'cu'", "[0, 90)");
	bad_library(HEAD CU_T(""), "'cu'", "template");
	bad_library(HEAD "{\"name\": \"cu\", \"kind\": \"metal\", \"nk\": {\"model\": "
	            "\"rakic1998-ld\", \"element\": \"Cu\"}, \"template\": {\"views\": [{"
	            "\"angle_deg\": 0, \"mean\": [0.5, 0.4], \"cov\": [0,0,0,0,0,0,0,0,0], "
	            "\"pixels\": 5}]}}]}", "'cu'", "mean (3");
	{
		const char *path = kg_tmpfile("lib/good.json", HEAD CU_T(VIEW(0, 1e-4) ", "
		                                                       VIEW(40, 2e-4)));
		kg_material_library *lib = NULL;
		kg_err e = {""};
		CHECK(kg_material_library_load(path, &lib, &e) == 0, "template library: %s", e.msg);
		const kg_material *cu = lib ? kg_material_library_find(lib, "cu") : NULL;
		CHECK(cu && cu->tmpl.n == 2 && cu->tmpl.angle_deg[1] == 40 &&
		          cu->tmpl.cov[1][0] == 2e-4 && cu->tmpl.mean[0][2] == 0.3 &&
		          cu->tmpl.pixels[0] == 500,
		      "the template read back");
		/* a template's own scatter is its model error: sd over the mean's level
		 * |mean| / sqrt(3), the largest view */
		double l = sqrt((0.5 * 0.5 + 0.4 * 0.4 + 0.3 * 0.3) / 3.0);
		CHECK(cu && fabs(cu->model_rsd[0] - sqrt(2e-4) / l) < 1e-12 &&
		          fabs(cu->model_rsd[1] - sqrt(1e-4) / l) < 1e-12 &&
		          fabs(cu->model_rsd[2] - sqrt(1e-4) / l) < 1e-12,
		      "template model_rsd %g %g %g, expected %g, %g, %g", cu ? cu->model_rsd[0] : 0,
		      cu ? cu->model_rsd[1] : 0, cu ? cu->model_rsd[2] : 0, sqrt(2e-4) / l,
		      sqrt(1e-4) / l, sqrt(1e-4) / l);
		kg_material_library_free(&lib);
	}
#undef VIEW
#undef CU_T
	bad_library("{\"format\": \"kogei-camera/1\", \"materials\": [" CU "]}", "format", NULL);
	bad_library("{\"format\": \"kogei-materials/1\", \"extra\": 1, \"materials\": [" CU "]}",
	            "extra", NULL);
	bad_library(HEAD CU ",]}", "bad.json:", NULL);
	bad_library(HEAD "{\"kind\": \"metal\"}]}", "materials[0]", "name");
	bad_library(HEAD "{\"name\": \"t\", \"kind\": \"metal\", \"nk\": \"tables/t.csv\"}]}",
	            "'t'", "tables/t.csv");

	/* n,k tables relative to the JSON file, CSV and YAML, and a spectral body */
	kg_tmpfile("lib/tables/t.csv", "wavelength_nm,n,k\n350,0.5,2\n750,0.3,4\n");
	kg_tmpfile("lib/tables/t.yml", "DATA:\n  - type: tabulated nk\n    data: |\n"
	           "        0.35 0.5 2\n        0.75 0.3 4\n");
	kg_tmpfile("lib/tables/short.csv", "wavelength_nm,n,k\n420,0.5,2\n750,0.3,4\n");
	const char *path = kg_tmpfile("lib/good.json", HEAD
	    "{\"name\": \"csv-metal\", \"kind\": \"metal\", \"nk\": \"tables/t.csv\"},"
	    "{\"name\": \"yaml-metal\", \"kind\": \"metal\", \"nk\": \"tables/t.yml\", "
	    " \"roughness\": 0.3, \"gloss\": 1, \"mirror\": 0},"
	    "{\"name\": \"short\", \"kind\": \"metal\", \"nk\": \"tables/short.csv\", "
	    " \"extrapolate\": true},"
	    "{\"name\": \"mix\", \"kind\": \"alloy\", \"components\": [{\"material\": "
	    "\"csv-metal\", \"fraction\": 0.5}, {\"material\": \"yaml-metal\", \"fraction\": "
	    "0.5}]},"
	    "{\"name\": \"lac\", \"kind\": \"dielectric\", \"n\": 1.5, \"body\": "
	    "{\"wavelength_nm\": [380, 780], \"reflectance\": [0.1, 0.5]}}]}");
	kg_material_library *lib = NULL;
	kg_err e = {""};
	CHECK(kg_material_library_load(path, &lib, &e) == 0, "%s", e.msg);
	if (!lib)
		return;
	const kg_material *c = kg_material_library_find(lib, "csv-metal"),
	                  *y = kg_material_library_find(lib, "yaml-metal"),
	                  *s = kg_material_library_find(lib, "short"),
	                  *l = kg_material_library_find(lib, "lac");
	CHECK(c && y && s && l, "entries present");
	if (c && y && s && l) {
		CHECK_NEAR(c->nk.n.v[30], 0.5 - 0.2 * 200 / 400, 1e-12, "csv n at 550 nm");
		CHECK(kg_spectrum_rmse(&c->nk.k, &y->nk.k) < 1e-12, "YAML = CSV");
		CHECK(y->roughness == 0.3 && y->gloss == 1 && y->mirror == 0, "surface fields");
		CHECK(c->roughness == 0.1 && c->mirror_width == 0.02 && c->gloss == 0.8 &&
		      c->mirror == 0.2, "defaults");
		CHECK(s->nk.n.v[0] == 0.5, "extrapolate holds the end value");
		CHECK_NEAR(l->body.v[30], 0.1 + 0.4 * 170 / 400, 1e-12, "body resampled");
	}
	kg_material_library_free(&lib);
}

int main(void)
{
	kg_tmpdir_create("kg_test_materials");
	validation();
	extremes();
	library_files();
	default_library();
	return kg_test_done("test_materials");
}
