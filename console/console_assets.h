/* The operator console's page as compiled in (console/gen_assets.c writes the table). */
#ifndef KG_CONSOLE_ASSETS_H
#define KG_CONSOLE_ASSETS_H
#include <stddef.h>
typedef struct kg_console_asset kg_console_asset;
struct kg_console_asset {
	const char *path, *type;
	const unsigned char *data;
	size_t size;
};
extern const kg_console_asset kg_console_assets[];
#endif
