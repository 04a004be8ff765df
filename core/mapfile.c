/* A file mapped for reading whose pages may vanish under it (mapfile.h). */
#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include "mapfile.h"

struct kg_mapfile {
	void *base;
	size_t len;
	int fd;
	int slot;
	struct stat st; /* the file as it was mapped */
	char *path;
};

/* The table the handler reads: a slot is free when its base is 0. Slots are claimed
 * and released under table_lock; the handler only reads them (atomically) and sets
 * damaged. */
enum { NSLOTS = 64 };
static struct {
	_Atomic uintptr_t base;
	_Atomic size_t len;
	atomic_int damaged;
} table[NSLOTS];
static pthread_mutex_t table_lock = PTHREAD_MUTEX_INITIALIZER;
static pthread_once_t handler_once = PTHREAD_ONCE_INIT;
static struct sigaction previous;

static void on_sigbus(int sig, siginfo_t *info, void *ctx)
{
	uintptr_t addr = (uintptr_t)info->si_addr;
	for (int i = 0; i < NSLOTS; i++) {
		uintptr_t b = atomic_load(&table[i].base);
		size_t n = atomic_load(&table[i].len);
		if (!b || addr < b || addr >= b + n)
			continue;
		/* the rest of this mapping as zero pages: a file cut short lost its tail */
		uintptr_t page = (uintptr_t)sysconf(_SC_PAGESIZE);
		uintptr_t from = addr & ~(page - 1);
		uintptr_t end = (b + n + page - 1) & ~(page - 1);
		int saved = errno;
		void *p = mmap((void *)from, end - from, PROT_READ,
		               MAP_FIXED | MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
		errno = saved;
		if (p != MAP_FAILED) {
			atomic_store(&table[i].damaged, 1);
			return;
		}
		break;
	}
	/* not ours: what was there before */
	if (previous.sa_flags & SA_SIGINFO && previous.sa_sigaction) {
		previous.sa_sigaction(sig, info, ctx);
		return;
	}
	if (previous.sa_handler != SIG_DFL && previous.sa_handler != SIG_IGN &&
	    previous.sa_handler) {
		previous.sa_handler(sig);
		return;
	}
	signal(SIGBUS, SIG_DFL); /* the fault repeats on return and ends the process */
}

static void install_handler(void)
{
	struct sigaction sa;
	memset(&sa, 0, sizeof(sa));
	sa.sa_sigaction = on_sigbus;
	sa.sa_flags = SA_SIGINFO | SA_ONSTACK;
	sigemptyset(&sa.sa_mask);
	sigaction(SIGBUS, &sa, &previous);
}

int kg_mapfile_open(int fd, size_t len, int populate, const char *path, kg_mapfile **out,
                    const void **base, kg_err *err)
{
	kg_check_arg(fd >= 0 && len > 0 && path && out && base, err);
	*out = NULL;
	*base = NULL;
	pthread_once(&handler_once, install_handler);
	kg_mapfile *m = calloc(1, sizeof(*m));
	if (!m || !(m->path = strdup(path))) {
		free(m);
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
	}
	m->fd = fcntl(fd, F_DUPFD_CLOEXEC, 0);
	m->slot = -1;
	if (m->fd < 0 || fstat(m->fd, &m->st)) {
		int e = errno;
		kg_mapfile_free(&m);
		return kg_fail(err, KG_EIO, "%s: cannot map: %s", path, strerror(e));
	}
	pthread_mutex_lock(&table_lock);
	for (int i = 0; i < NSLOTS && m->slot < 0; i++)
		if (!atomic_load(&table[i].base))
			m->slot = i;
	void *p = MAP_FAILED;
	if (m->slot >= 0) {
		p = mmap(NULL, len, PROT_READ, MAP_PRIVATE | (populate ? MAP_POPULATE : 0), m->fd,
		         0);
		if (p != MAP_FAILED) {
			atomic_store(&table[m->slot].len, len);
			atomic_store(&table[m->slot].damaged, 0);
			atomic_store(&table[m->slot].base, (uintptr_t)p);
		}
	}
	pthread_mutex_unlock(&table_lock);
	if (p == MAP_FAILED) {
		int full = m->slot < 0;
		m->slot = -1;
		kg_mapfile_free(&m);
		return kg_fail(err, KG_EIO, "%s: cannot map: %s", path,
		               full ? "too many files mapped at once" : strerror(errno));
	}
	m->base = p;
	m->len = len;
	*out = m;
	*base = p;
	return 0;
}

int kg_mapfile_check(const kg_mapfile *m, kg_err *err)
{
	kg_check_arg(m, err);
	struct stat now = {0};
	int cut = m->slot >= 0 && atomic_load(&table[m->slot].damaged);
	int changed = fstat(m->fd, &now) || now.st_size != m->st.st_size ||
	              now.st_mtim.tv_sec != m->st.st_mtim.tv_sec ||
	              now.st_mtim.tv_nsec != m->st.st_mtim.tv_nsec;
	if (cut || changed)
		return kg_fail(err, KG_EIO,
		               "%s: the file was %s by another program while it was read (%lld "
		               "bytes when opened, %lld now): nothing was written from it; read it "
		               "again when it is complete",
		               m->path, cut ? "cut short" : "changed", (long long)m->st.st_size,
		               (long long)now.st_size);
	return 0;
}

void kg_mapfile_free(kg_mapfile **mp)
{
	if (!mp || !*mp)
		return;
	kg_mapfile *m = *mp;
	if (m->base) {
		pthread_mutex_lock(&table_lock);
		if (m->slot >= 0)
			atomic_store(&table[m->slot].base, 0);
		munmap(m->base, m->len);
		pthread_mutex_unlock(&table_lock);
	}
	if (m->fd >= 0)
		close(m->fd);
	free(m->path);
	free(m);
	*mp = NULL;
}
