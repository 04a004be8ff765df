#include "memutil.h"

#include <stdint.h>
#include <sys/mman.h>
#include <unistd.h>

void kg_advise_huge_pages(void *p, size_t n)
{
#if defined(MADV_HUGEPAGE)
	/* below one huge page there is nothing to gain */
	if (!p || n < ((size_t)2 << 20))
		return;
	uintptr_t page = (uintptr_t)sysconf(_SC_PAGESIZE);
	uintptr_t a = ((uintptr_t)p + page - 1) / page * page;
	uintptr_t b = ((uintptr_t)p + n) / page * page;
	if (b > a)
		(void)madvise((void *)a, b - a, MADV_HUGEPAGE);
#else
	(void)p, (void)n;
#endif
}
