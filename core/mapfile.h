/* A file mapped for reading whose pages may vanish under it.
 *
 * A mapping's pages are the file's: when another program cuts the file short while it
 * is mapped, a read of a page past the new end raises SIGBUS, and a program that does
 * not catch it dies without a word. kg_mapfile keeps every mapping it makes in a
 * process-wide table, and one SIGBUS handler (installed with the first mapping) serves
 * them all: a fault inside a mapping of the table replaces the rest of that mapping,
 * from the faulting page to its end, with zero pages and marks the mapping damaged, so
 * the read goes on (reading zeros) in whatever thread made it. A fault anywhere else
 * is passed to the handler that was there before, or takes SIGBUS's default course.
 *
 * A reader checks kg_mapfile_check when it is done with the pages and before it
 * writes anything from them: it fails when a page vanished or when the file was
 * changed in place (its size or modification time differ from when it was mapped),
 * naming the file. Replacing the file by a rename is safe: the mapping keeps the old
 * file. */
#ifndef KG_MAPFILE_H
#define KG_MAPFILE_H

#include <stddef.h>

#include "error.h"

typedef struct kg_mapfile kg_mapfile;

/* Map len bytes of the open file fd (the caller keeps fd; kg_mapfile holds its own
 * duplicate) read-only; populate asks for the page tables to be filled at once
 * (MAP_POPULATE). path names the file in messages. The address is *base. KG_EIO with
 * a message when the file cannot be mapped (the caller may read it instead). */
int kg_mapfile_open(int fd, size_t len, int populate, const char *path, kg_mapfile **out,
                    const void **base, kg_err *err);

/* 0 while the mapping still holds the file as it was mapped; KG_EIO naming the file
 * when a page vanished (the file was cut short) or the file was changed in place. */
int kg_mapfile_check(const kg_mapfile *m, kg_err *err);

/* Unmap, close and forget; *m becomes NULL. */
void kg_mapfile_free(kg_mapfile **m);

#endif
