/* btf_mem.c - large buffers (block matrices, whole materials) on transparent huge
 * pages where the kernel offers them on request, and one freed buffer kept for the
 * next request it can hold. */
#include "btf_common.h"

#include <pthread.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

/* The huge page of x86-64 and arm64 with 4 KiB pages, and the size from which a
 * buffer asks for them: below it the few faults cost nothing worth the alignment. */
#define BTF__HUGE_PAGE ((size_t)2 << 20)
#define BTF__BIG_MIN ((size_t)8 << 20)
/* The largest buffer btf_big_free keeps for the next request: a 64x64 material's
 * block matrix of every view (322 MB) is; a 256x256 one's (5.2 GB) is not kept. */
#define BTF__SPARE_MAX ((size_t)1 << 30)

/* The one buffer btf_big_free kept (NULL when none) and its bytes; the process's,
 * until the next btf_big_alloc it can hold takes it. */
static struct {
    void *p;
    size_t bytes;
} btf__spare;
static pthread_mutex_t btf__spare_lock = PTHREAD_MUTEX_INITIALIZER;

/* The kept buffer when it holds bytes, else NULL. */
static void *btf__spare_take(size_t bytes)
{
    void *p = NULL;
    pthread_mutex_lock(&btf__spare_lock);
    if (btf__spare.p && btf__spare.bytes >= bytes)
        p = btf__spare.p, btf__spare.p = NULL, btf__spare.bytes = 0;
    pthread_mutex_unlock(&btf__spare_lock);
    return p;
}

void btf_big_free(void *p, size_t bytes)
{
    if (!p || bytes < BTF__BIG_MIN || bytes > BTF__SPARE_MAX) {
        free(p);
        return;
    }
    pthread_mutex_lock(&btf__spare_lock);
    if (btf__spare.bytes < bytes) { /* the larger one is kept */
        void *old = btf__spare.p;
        btf__spare.p = p, btf__spare.bytes = bytes, p = old;
    }
    pthread_mutex_unlock(&btf__spare_lock);
    free(p);
}

void *btf_big_alloc(size_t bytes)
{
    if (bytes < BTF__BIG_MIN)
        return malloc(bytes ? bytes : 1);
    void *p = btf__spare_take(bytes);
    if (p)
        return p;
    if (posix_memalign(&p, BTF__HUGE_PAGE, bytes) != 0)
        return NULL;
#ifdef MADV_HUGEPAGE
    (void)madvise(p, bytes, MADV_HUGEPAGE); /* a hint: where it is refused, small pages */
#endif
    return p;
}

void *btf_big_calloc(size_t n, size_t size)
{
    if (size && n > SIZE_MAX / size)
        return NULL;
    void *p = btf_big_alloc(n * size);
    if (p)
        memset(p, 0, n * size);
    return p;
}
