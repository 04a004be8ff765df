/* The registry of inputs: a file read through core's readers cannot be the output of a
 * writer, whether the output names it, a hard link to it or a symbolic link to it, and
 * the refusal leaves the input's bytes as they were and no temporary file behind. An
 * ENVI cube is refused when either of its two files is an input. */
#include <string.h>

#include "io_util.h"
#include "kg_core.h"
#include "kg_test.h"

static const char text[] = "CGATS.17\nthe input's bytes\n";

static void expect_refused(int rc, const kg_err *e, const char *out, const char *input)
{
	CHECK(rc == KG_EINVAL, "%s: expected KG_EINVAL, got %d", out, rc);
	CHECK(strstr(e->msg, "is an input of this command") && strstr(e->msg, out) &&
	          strstr(e->msg, input) && strstr(e->msg, "choose another output name"),
	      "%s: message '%s' does not name the output and the input %s", out, e->msg, input);
}

/* The input still holds exactly its bytes. */
static void expect_intact(const char *path, const char *want, size_t n)
{
	char *buf = NULL;
	size_t len = 0;
	kg_err e = {{0}};
	CHECK(kg_read_file(path, &buf, &len, &e) == 0, "%s: %s", path, e.msg);
	CHECK(buf && len == n && memcmp(buf, want, n) == 0, "%s: the input was changed", path);
	free(buf);
}

static int write_text(const char *path, kg_err *e)
{
	kg_outfile o;
	int rc = kg_outfile_open(&o, path, 0, e);
	if (rc)
		return rc;
	fputs("overwritten\n", o.fp);
	return kg_outfile_commit(&o, e);
}

int main(void)
{
	io_tmpdir("inputs");
	const char *in = kg_test_path("a.cgats");
	io_write_bytes(in, text, strlen(text));
	const char *hard = kg_test_path("hard.cgats"), *sym = kg_test_path("sym.cgats");
	CHECK(link(in, hard) == 0 && symlink("a.cgats", sym) == 0, "cannot make links");
	kg_err e = {{0}};

	/* Not read yet: writing over it is allowed (and nothing checks names alone). */
	CHECK(kg_inputs_check_output(in, &e) == 0, "%s", e.msg);
	char *buf = NULL;
	CHECK(kg_read_file(in, &buf, NULL, &e) == 0, "%s", e.msg);
	free(buf);
	int files = io_count_files();

	const char *outs[3] = {in, hard, sym};
	for (int i = 0; i < 3; i++) {
		memset(&e, 0, sizeof(e));
		expect_refused(kg_inputs_check_output(outs[i], &e), &e, outs[i], in);
		memset(&e, 0, sizeof(e));
		expect_refused(write_text(outs[i], &e), &e, outs[i], in);
		json_t *root = json_object();
		memset(&e, 0, sizeof(e));
		expect_refused(kg_json_write(root, outs[i], &e), &e, outs[i], in);
		json_decref(root);
	}
	expect_intact(in, text, strlen(text));
	CHECK(io_count_files() == files, "a refused write left %d file(s) behind",
	      io_count_files() - files);
	/* A new name, and standard output, never collide. */
	CHECK(kg_inputs_check_output(kg_test_path("new.cgats"), &e) == 0, "%s", e.msg);
	CHECK(kg_inputs_check_output("-", &e) == 0, "%s", e.msg);

	/* A file that becomes an input while an output is open is refused at commit. */
	const char *late = kg_test_path("late.txt");
	kg_outfile o;
	CHECK(kg_outfile_open(&o, late, 0, &e) == 0, "%s", e.msg);
	fputs("output\n", o.fp);
	io_write_bytes(late, "late input\n", 11);
	CHECK(kg_read_file(late, &buf, NULL, &e) == 0, "%s", e.msg);
	free(buf);
	memset(&e, 0, sizeof(e));
	expect_refused(kg_outfile_commit(&o, &e), &e, late, late);
	expect_intact(late, "late input\n", 11);
	CHECK(io_count_files() == files + 1, "commit refused but left its temporary file");

	/* Forgotten (a file read to be rewritten by its owner), then writable. */
	kg_inputs_forget(late);
	CHECK(write_text(late, &e) == 0, "%s", e.msg);

	/* Images: TIFF and PNG readers note what they read. */
	kg_image *img = NULL;
	CHECK(kg_image_new(4, 3, 3, &img, &e) == 0, "%s", e.msg);
	for (int f = 0; f < 2 && img; f++) {
		const char *p = kg_test_path(f ? "img.png" : "img.tif");
		CHECK(kg_image_write(img, p, 16, &e) == 0, "%s", e.msg);
		char *before = NULL;
		size_t nb = 0;
		kg_read_file(p, &before, &nb, &e);
		kg_inputs_reset();
		CHECK(kg_inputs_check_output(p, &e) == 0, "reset left %s registered", p);
		kg_image *back = NULL;
		CHECK(kg_image_read(p, &back, &e) == 0, "%s", e.msg);
		kg_image_free(&back);
		memset(&e, 0, sizeof(e));
		expect_refused(kg_image_write(img, p, 8, &e), &e, p, p);
		expect_intact(p, before, nb);
		free(before);
	}
	kg_image_free(&img);

	/* ENVI: both the header and the data file of an input cube are inputs; an output
	 * whose header is new but whose data file is a hard link to the input's data is
	 * refused before anything is written. */
	float cube[2 * 2 * 1] = {1, 2, 3, 4};
	kg_envi_meta m = {.samples = 2, .lines = 2, .bands = 1, .data_type = KG_ENVI_F32};
	CHECK(kg_envi_write(kg_test_path("c.hdr"), &m, KG_LAYOUT_BIP, cube, &e) == 0, "%s", e.msg);
	kg_inputs_reset();
	kg_envi *env = NULL;
	CHECK(kg_envi_open(kg_test_path("c.hdr"), &env, &e) == 0, "%s", e.msg);
	kg_envi_close(&env);
	CHECK(link(kg_test_path("c.img"), kg_test_path("d.img")) == 0, "cannot link the data file");
	files = io_count_files();
	const char *cubes[3] = {kg_test_path("c.hdr"), kg_test_path("c.img"), kg_test_path("d.hdr")};
	const char *hits[3] = {"c.hdr", "c.img", "d.img"};
	for (int i = 0; i < 3; i++) {
		memset(&e, 0, sizeof(e));
		int rc = kg_envi_write(cubes[i], &m, KG_LAYOUT_BIP, cube, &e);
		CHECK(rc == KG_EINVAL && strstr(e.msg, hits[i]) &&
		          strstr(e.msg, "is an input of this command"),
		      "%s: expected a refusal naming %s, got %d '%s'", cubes[i], hits[i], rc, e.msg);
	}
	CHECK(io_count_files() == files, "a refused cube left %d file(s) behind",
	      io_count_files() - files);

	kg_inputs_reset();
	CHECK(write_text(in, &e) == 0, "after reset: %s", e.msg);
	return kg_test_done("inputs");
}
