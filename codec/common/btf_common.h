/* btf_common.h - plumbing shared by the codec's rooms and the project's other
 * rooms, not part of the installed API: error formatting, name lookup, area
 * weights, 8-bit view columns, large buffers, a monotonic clock. Implemented in
 * btf_core.c, btf_views.c and btf_mem.c.
 */
#ifndef BTF_COMMON_H
#define BTF_COMMON_H

#include <stddef.h>
#include <stdint.h>

#include "btf.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Index of name in names[0..n-1] (exact match), -1 if absent or NULL: the one
 * name-to-enum lookup of every module with named values. */
int btf_name_index(const char *const *names, int n, const char *name);

/* Formats into err (if non-NULL; control characters become ?, so the message is one
 * line) and returns code: for use by library modules. */
btf_result btf_fail(btf_error *err, btf_result code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* Area-weighted resampling from n_in to n_out <= n_in samples along one axis (the
 * box filter, also for sizes that do not divide): output i covers
 * [i*n_in/n_out, (i+1)*n_in/n_out) in input units and input sample first[i] + s
 * (s < cnt[i]) weighs w[i*maxc + s], its overlap over the width; the weights of an
 * output sum to 1. maxc >= n_in/n_out + 2 always suffices; 0, or -1 when an output
 * would need more than maxc inputs. */
int btf_area_weights(int n_in, int n_out, int *first, int *cnt, float *w, int maxc);

/* Planar columns of one interleaved 8-bit RGB image (texels*3 bytes) into
 * cols[c * texels + i] = px[3 i + c] * (1/255), the scale of btf_get. */
void btf_views_put_u8(const uint8_t *px, size_t texels, float *cols);

/* A buffer of bytes for free() or btf_big_free(): from 8 MiB up aligned to 2 MiB and
 * marked for transparent huge pages (madvise; a hint the kernel may ignore), so that
 * filling it takes one page fault per 2 MiB instead of per 4 KiB. A 64x64 material's
 * block matrix of every view (322 MB) is filled several times per budget search. NULL
 * when out of memory. btf_big_calloc zeroes it (NULL also when n * size overflows).
 * btf_big_free(p, bytes) (bytes as asked) keeps one buffer of 8 MiB to 1 GiB, the
 * largest freed, for the next btf_big_alloc it can hold: a block matrix filled again
 * then skips the kernel's zeroing of fresh pages (its contents are left as they were). */
void *btf_big_alloc(size_t bytes);
void *btf_big_calloc(size_t n, size_t size);
void btf_big_free(void *p, size_t bytes);

/* Monotonic clock in seconds (CLOCK_MONOTONIC): for durations only. */
double btf_seconds(void);

/* Gives this thread's list interpolation (btf_interp.c) t, the table of list set d
 * that btf_dirset_make_list has just built and checked, so that the first
 * btf_dirset_interp of d does not build the same table again. Takes t over. */
struct btf_dirtab;
void btf_interp_keep_list(const btf_dirset *d, struct btf_dirtab *t);

#ifdef __cplusplus
}
#endif
#endif
