/* btf_mem.c - large buffers (block matrices, whole materials) on transparent huge
 * pages where the kernel offers them on request. */
#include "btf_common.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

/* The huge page of x86-64 and arm64 with 4 KiB pages, and the size from which a
 * buffer asks for them: below it the few faults cost nothing worth the alignment. */
#define BTF__HUGE_PAGE ((size_t)2 << 20)
#define BTF__BIG_MIN ((size_t)8 << 20)

void *btf_big_alloc(size_t bytes)
{
    if (bytes < BTF__BIG_MIN)
        return malloc(bytes ? bytes : 1);
    void *p = NULL;
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
