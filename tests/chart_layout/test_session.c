/* The chart layout a session's manifest names (kg_chart_layout_resolve_session, used by
 * kogei process and the console): a bundled layout's name, or a regular file under
 * captures/ of the session reached with no symbolic link. /etc/passwd, "../x.json", an
 * escape through "..", a name that is no bundled layout (even one that exists as a
 * file in the current folder), a symbolic link inside the session to a file outside:
 * each refused with KG_EINVAL naming the manifest and the key, and no path given. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "kg_calib.h"
#include "kg_test.h"

static char dir[256];

static void put(const char *rel, const char *text)
{
	char p[512];
	snprintf(p, sizeof(p), "%s/%s", dir, rel);
	FILE *fp = fopen(p, "w");
	CHECK(fp != NULL, "cannot write %s", p);
	if (fp) {
		fputs(text, fp);
		fclose(fp);
	}
}

int main(void)
{
	snprintf(dir, sizeof(dir), "/tmp/kg-layout-session-XXXXXX");
	CHECK(mkdtemp(dir) != NULL, "mkdtemp");
	char p[512], manifest[512];
	snprintf(manifest, sizeof(manifest), "%s/session.json", dir);
	snprintf(p, sizeof(p), "%s/captures", dir);
	mkdir(p, 0755);
	snprintf(p, sizeof(p), "%s/captures/chart-0001", dir);
	mkdir(p, 0755);
	snprintf(p, sizeof(p), "%s/captures/chart-0002", dir);
	mkdir(p, 0755);
	put("captures/chart-0001/layout.json", "{}");
	put("outside.json", "{}");
	snprintf(p, sizeof(p), "%s/captures/chart-0002/layout.json", dir);
	CHECK(symlink("/etc/passwd", p) == 0, "symlink");
	snprintf(p, sizeof(p), "%s/captures/linked", dir);
	CHECK(symlink(dir, p) == 0, "symlink");

	/* accepted */
	char *path = NULL;
	kg_err err = {{0}};
	int ret = kg_chart_layout_resolve_session(dir, manifest, "captures[0].chart_layout",
	                                          "colorchecker24-frame", &path, &err);
	CHECK(ret == 0 && path && kg_test_file_exists(path), "bundled name: %d %s", ret, err.msg);
	free(path);
	path = NULL;
	ret = kg_chart_layout_resolve_session(dir, manifest, "captures[0].chart_layout",
	                                      "captures/chart-0001/layout.json", &path, &err);
	snprintf(p, sizeof(p), "%s/captures/chart-0001/layout.json", dir);
	CHECK(ret == 0 && path && !strcmp(path, p), "file in the session: %d %s", ret, err.msg);
	free(path);

	/* refused; "outside.json" also exists in the current folder */
	CHECK(chdir(dir) == 0, "chdir");
	static const char *const bad[] = {
		"/etc/passwd", "../x.json", "captures/chart-0001/../../../etc/passwd",
		"captures/../outside.json", "outside.json", "passwd",
		"captures/chart-0002/layout.json", /* a link to /etc/passwd */
		"captures/linked/chart-0001/layout.json", /* a link on the way */
		"captures/chart-0001/missing.json", "captures/chart-0001",
	};
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		memset(&err, 0, sizeof(err));
		path = (char *)"unchanged";
		ret = kg_chart_layout_resolve_session(dir, manifest, "captures[3].chart_layout", bad[i],
		                                      &path, &err);
		char want[600];
		snprintf(want, sizeof(want), "%s: captures[3].chart_layout: '%s': expected", manifest,
		         bad[i]);
		CHECK(ret == KG_EINVAL && !path && strstr(err.msg, want),
		      "'%s': %d: %s (path %s)", bad[i], ret, err.msg, path ? path : "NULL");
	}
	CHECK(chdir("/") == 0, "chdir");
	char cmd[600];
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", dir);
	CHECK(system(cmd) == 0, "cleanup");
	return kg_test_done("chart-layout-session");
}
