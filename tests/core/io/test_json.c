/* JSON helpers: values found by key path, and error messages that name the file, the
 * key and what was expected; syntax errors with line and column; atomic writes that
 * read back the same doubles. */
#include <string.h>

#include "io_util.h"
#include "kg_core.h"
#include "kg_test.h"

static const char *doc =
	"{\n"
	"  \"format\": \"kogei-reference/1\",\n"
	"  \"K\": 3,\n"
	"  \"half\": 0.5,\n"
	"  \"M\": [[1, 2, 3], [4, 5, 6]],\n"
	"  \"ragged\": [[1, 2], [3]],\n"
	"  \"rho0\": [0.25, 0.5, 0.75],\n"
	"  \"devices\": {\"camera\": {\"id\": \"sim:0\", \"gain\": \"high\"}},\n"
	"  \"patches\": [{\"id\": \"A1\"}, {\"id\": \"A2\", \"rgb\": [0.1, 0.2, 0.3]}]\n"
	"}\n";

#define EXPECT_MSG(call, ...)                                                               \
	do {                                                                                    \
		kg_err e_ = {{0}};                                                                  \
		kg_err *ep = &e_;                                                                   \
		int r_ = (call);                                                                    \
		CHECK(r_ < 0, "%s: expected failure", #call);                                       \
		const char *want_[] = {__VA_ARGS__};                                                \
		for (size_t i_ = 0; i_ < sizeof(want_) / sizeof(want_[0]); i_++)                    \
			CHECK(strstr(e_.msg, want_[i_]), "%s: message '%s' lacks '%s'", #call, e_.msg, \
			      want_[i_]);                                                               \
	} while (0)

int main(void)
{
	io_tmpdir("json");
	const char *f = kg_test_path("ref.json");
	io_write_bytes(f, doc, strlen(doc));
	json_t *root = NULL;
	kg_err err = {{0}};
	CHECK(kg_json_load(f, &root, &err) == 0, "load: %s", err.msg);
	if (!root)
		return kg_test_done("json");

	const char *s;
	double d;
	long k;
	double v[3];
	kg_mat *m = NULL;
	CHECK(kg_json_get_string(f, root, "format", &s, &err) == 0 && strcmp(s, "kogei-reference/1") == 0,
	      "string");
	CHECK(kg_json_get_number(f, root, "half", &d, &err) == 0 && d == 0.5, "number");
	CHECK(kg_json_get_int(f, root, "K", 1, 61, &k, &err) == 0 && k == 3, "int");
	CHECK(kg_json_get_numbers(f, root, "rho0", 3, v, &err) == 0 && v[2] == 0.75, "numbers");
	CHECK(kg_json_get_string(f, root, "devices.camera.id", &s, &err) == 0 && strcmp(s, "sim:0") == 0,
	      "nested");
	CHECK(kg_json_get_numbers(f, root, "patches[1].rgb", 3, v, &err) == 0 && v[1] == 0.2,
	      "array index in path: %s", err.msg);
	CHECK(kg_json_get_matrix(f, root, "M", 2, 3, &m, &err) == 0 && kg_mat_get(m, 1, 2) == 6,
	      "matrix: %s", err.msg);
	kg_mat_free(&m);
	CHECK(kg_json_get_matrix(f, root, "M", KG_JSON_ANY, KG_JSON_ANY, &m, &err) == 0 &&
	      m->rows == 2 && m->cols == 3, "matrix of any size");
	kg_mat_free(&m);
	CHECK(kg_json_find(root, "devices.camera.missing") == NULL, "find: missing is NULL");
	CHECK(kg_json_find(root, "patches[0].id") != NULL, "find: present");

	/* Each error names the file, the key path and what was expected. */
	EXPECT_MSG(kg_json_get_number(f, root, "missing", &d, ep), "ref.json", "'missing' is missing");
	EXPECT_MSG(kg_json_get_number(f, root, "format", &d, ep), "ref.json", "'format'",
	           "expected a number, got a string");
	EXPECT_MSG(kg_json_get_string(f, root, "K", &s, ep), "'K'", "expected a string, got a number");
	EXPECT_MSG(kg_json_get_int(f, root, "half", 0, 10, &k, ep), "'half'", "expected an integer");
	EXPECT_MSG(kg_json_get_int(f, root, "K", 4, 10, &k, ep), "'K'", "from 4 to 10");
	EXPECT_MSG(kg_json_get_numbers(f, root, "rho0", 4, (double[4]){0}, ep), "'rho0'",
	           "expected 4 numbers, got 3");
	EXPECT_MSG(kg_json_get_numbers(f, root, "devices", 3, v, ep), "'devices'",
	           "expected an array of 3 numbers, got an object");
	EXPECT_MSG(kg_json_get_string(f, root, "devices.camera.serial", &s, ep), "ref.json",
	           "'devices.camera.serial' is missing");
	EXPECT_MSG(kg_json_get_string(f, root, "devices.camera.gain.max", &s, ep),
	           "'devices.camera.gain'", "expected an object, got a string");
	EXPECT_MSG(kg_json_get_string(f, root, "patches[5].id", &s, ep), "'patches'",
	           "expected at least 6 elements, got 2");
	EXPECT_MSG(kg_json_get_numbers(f, root, "patches[0].rgb", 3, v, ep),
	           "'patches[0].rgb' is missing");
	EXPECT_MSG(kg_json_get_matrix(f, root, "M", 3, 3, &m, ep), "'M'", "expected an array of 3 rows, got 2");
	EXPECT_MSG(kg_json_get_matrix(f, root, "M", 2, 2, &m, ep), "'M[0]'", "expected 2 numbers, got 3");
	EXPECT_MSG(kg_json_get_matrix(f, root, "ragged", KG_JSON_ANY, KG_JSON_ANY, &m, ep),
	           "'ragged[1]'", "expected 2 numbers, got 1");
	CHECK(m == NULL, "no matrix on failure");
	json_decref(root);

	/* Syntax errors point at line and column; duplicates are refused. */
	const char *bad = kg_test_path("bad.json");
	io_write_bytes(bad, "{\n  \"a\": 1,\n  \"b\": [1, 2,]\n}\n", 28);
	EXPECT_MSG(kg_json_load(bad, &root, ep), "bad.json:3:");
	io_write_bytes(bad, "{\"a\": 1, \"a\": 2}", 16);
	EXPECT_MSG(kg_json_load(bad, &root, ep), "bad.json:1:", "duplicate");
	CHECK(kg_json_load(kg_test_path("none.json"), &root, &err) == KG_ENOENT, "missing file: %s", err.msg);

	/* Writing: atomic, indented, doubles exact, insertion order kept. */
	json_t *out = json_object();
	json_object_set_new(out, "format", json_string("kogei-camera/1"));
	double tricky[3] = {0.1, 1.0 / 3.0, 6.02214076e23};
	json_t *arr;
	CHECK(kg_json_numbers(tricky, 3, &arr, &err) == 0, "numbers to JSON");
	json_object_set_new(out, "values", arr);
	kg_mat *I;
	kg_mat_identity(3, &I, NULL);
	json_t *mj;
	CHECK(kg_json_matrix(I, &mj, &err) == 0, "matrix to JSON");
	json_object_set_new(out, "M2", mj);
	I->a[4] = NAN;
	mj = NULL;
	CHECK(kg_json_matrix(I, &mj, &err) == KG_EINVAL && !mj && strstr(err.msg, "(1, 1)"),
	      "NaN refused: %s", err.msg);
	kg_mat_free(&I);
	const char *o = kg_test_path("out.json");
	int before = io_count_files();
	CHECK(kg_json_write(out, o, &err) == 0, "write: %s", err.msg);
	CHECK(io_count_files() == before + 1, "no temporary left");
	char *text;
	kg_read_file(o, &text, NULL, NULL);
	CHECK(text && strncmp(text, "{\n  \"format\": \"kogei-camera/1\",\n  \"values\"", 42) == 0,
	      "indented, insertion order: %s", text);
	CHECK(text && text[strlen(text) - 1] == '\n', "trailing newline");
	free(text);
	CHECK(kg_json_load(o, &root, &err) == 0 &&
	      kg_json_get_numbers(o, root, "values", 3, v, &err) == 0,
	      "read back: %s", err.msg);
	CHECK(v[0] == tricky[0] && v[1] == tricky[1] && v[2] == tricky[2], "doubles exact");
	json_decref(root);
	CHECK(kg_json_write(out, kg_test_path("nodir/x.json"), &err) < 0, "unwritable path fails");
	json_decref(out);
	return kg_test_done("json");
}
