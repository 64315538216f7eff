/* btf_views.h - a BTF read one view at a time: what k-view PCA needs, so a
 * material larger than memory can be compressed block by block.
 *
 *     btf_views s;
 *     btf_error err;
 *     if (btf_views_open("dome/", NULL, &s, &err) != BTF_OK) puts(err.msg);  // images or .btf
 *     float *cols = malloc(btf_views_floats(&s) * sizeof(float));
 *     btf_views_fill(&s, view, cols, &err);   // cols[(light*3 + c) * texels + y*width + x]
 *     free(cols);
 *     btf_views_close(&s);
 *
 * fill writes one view's samples on the byte/255 scale as 3 * n_lights planar
 * columns of width*height texels each: exactly the columns that view owns in a
 * block's data matrix (btf_pca.h), so the PCA fills its matrix without a copy.
 * Every source gives the same floats the in-memory BTF of the same input would
 * (btf_get), so a streamed compression equals the in-memory one bit for bit.
 *
 * Sources: an in-memory BTF (btf_views_wrap, nothing copied), an image
 * directory (the view's images decoded on each fill, missing ones interpolated
 * when asked, saturated samples counted), a DFMF `.btf` file (its factors held,
 * the view's rows decoded on each fill), or any source of one's own (fill
 * and close set by hand; bench/gen/btf_gen.h renders views this way).
 * Memory: a source holds at most one view's images (plus, for a `.btf`, its
 * factors, bounded by BTF_VIEWS_MAX_FACTOR_BYTES); not the material.
 */
#ifndef BTF_VIEWS_H
#define BTF_VIEWS_H

#include "btf.h"
#include "btf_io.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Largest DFMF factor set (U and S x V of the three channels, as floats) a streamed
 * `.btf` source holds: 3 GiB. A file needing more is refused with its size. */
#define BTF_VIEWS_MAX_FACTOR_BYTES ((size_t)3 << 30)

/* A source of views; filled by an opener, owned by the caller, released with
 * btf_views_close (after which impl is gone); lives as long as the caller keeps it. */
typedef struct btf_views {
    int width, height;
    btf_dirset lights, views;
    const char *name; /* for messages (the path); not owned */
    /* Writes view (canonical index) into cols (btf_views_floats floats). */
    btf_result (*fill)(struct btf_views *s, int view, float *cols, btf_error *err);
    void (*close)(struct btf_views *s); /* releases impl; NULL = nothing to release */
    void *impl;
    /* What the source noticed while filling (for warnings; image directories only,
     * each view counted once however often it is filled): images interpolated and
     * samples at 255. */
    int n_filled;
    btf_load_report report;
} btf_views;

/* Floats of one view: 3 * n_lights * width * height. */
size_t btf_views_floats(const btf_views *s);
btf_result btf_views_fill(btf_views *s, int view, float *cols, btf_error *err);
void btf_views_close(btf_views *s);

/* A view source over b (not copied; b must outlive it). */
void btf_views_wrap(const btf *b, btf_views *out);
/* A view source with inner's size, direction sets and name whose views fill gives
 * (impl its state): a filter or observer of inner's views. inner keeps its own counts
 * (n_filled, report) and is closed by its owner; out has nothing to close. */
void btf_views_over(const btf_views *inner,
                    btf_result (*fill)(btf_views *s, int view, float *cols, btf_error *err), void *impl,
                    btf_views *out);

/* Opens an image directory (the loaders' options: sampling, fill_missing,
 * downsample; storage must be 0 or BTF_U8) or a `.btf` file (storage 0 = float,
 * as btf_load_dfmf decodes it). Scans and checks what it can before the first
 * fill: every (light, view) image present (or fill_missing), image headers of one
 * size; a `.btf`'s header and factor sizes. A thesis package is
 * BTF_ERR_UNSUPPORTED (load it with btf_load_any). */
btf_result btf_views_open(const char *path, const btf_load_options *opt, btf_views *out, btf_error *err);

/* Reads every view of s into a new BTF (BTF_F32, or BTF_U8 when u8 is nonzero and
 * every value is a byte/255): for tests and small sources. */
btf_result btf_views_load(btf_views *s, int u8, btf **out, btf_error *err);

/* Writes every view of s as a UBO2003-named image directory (as btf_save_ubo2003_dir:
 * values rounded to bytes), one view in memory at a time. */
btf_result btf_views_save_ubo2003(btf_views *s, const char *dir, const char *prefix, const char *ext,
                                  btf_error *err);

#ifdef __cplusplus
}
#endif
#endif
