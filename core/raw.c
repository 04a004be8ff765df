/* Camera raw files through LibRaw (raw.h). Placeholder while the decoder is written. */
#include "kg_config.h"

#include <math.h>
#include <string.h>

#include "raw.h"

int kg_raw_available(void)
{
	return 0;
}

const char *kg_raw_version(void)
{
	return NULL;
}

int kg_raw_is_raw(const char *path)
{
	(void)path;
	return 0;
}

int kg_raw_read(const char *path, kg_image **out, kg_raw_meta *meta, kg_err *err)
{
	(void)out;
	(void)meta;
	return kg_fail(err, KG_ENOTSUP, "%s: raw decoding is not written yet", path);
}

int kg_raw_read_memory(const void *data, size_t size, const char *name, kg_image **out,
                       kg_raw_meta *meta, kg_err *err)
{
	(void)data;
	(void)size;
	(void)out;
	(void)meta;
	return kg_fail(err, KG_ENOTSUP, "%s: raw decoding is not written yet", name);
}

int kg_raw_read_meta(const char *path, kg_raw_meta *meta, kg_err *err)
{
	(void)meta;
	return kg_fail(err, KG_ENOTSUP, "%s: raw decoding is not written yet", path);
}
