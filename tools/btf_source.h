/* btf_source.h - the command-line tools' one way to name an input BTF.
 *
 *     btf_source_load("gen:knit:64", &opt, &b, &err);      // generated in memory
 *     btf_source_load("wool/", &opt, &b, &err);            // anything btf_load_any reads
 *
 * "gen:KIND[:SIZE[:SEED]]" generates KIND (knit, tiles, stone) at SIZE x SIZE
 * texels (default 64), seed SEED (default the kind's), sampled at opt->sampling
 * (default UBO2003) for lights and views, without writing any file. An image
 * directory in another sampling is read with opt->sampling set (--sampling), or
 * without it when the names fit exactly one built-in set.
 */
#ifndef BTF_SOURCE_H
#define BTF_SOURCE_H

#include "btf_io.h"
#include "btf_views.h"

btf_result btf_source_load(const char *spec, const btf_load_options *opt, btf **out, btf_error *err);

/* The direction set a --sampling value names: "ubo2003", "dome151" or a JSON file
 * (doc/data-model.md section 2). */
btf_result btf_source_sampling(const char *name, btf_dirset *d, btf_error *err);

/* The input options every command that reads a BTF takes; plain value, strings
 * point into argv. */
typedef struct btf_source_args {
    int downsample;       /* --downsample F */
    const char *sampling; /* --sampling S; NULL: inferred from the input (btf_load_ubo2003_dir) */
    int fill_missing;     /* --fill-missing: interpolate missing images, with a warning */
    btf_storage storage;  /* 0: the loader's own (btf_load_options.storage) */
    int width, height;    /* 0: native; else a thesis package's size (btf_load_options.width) */
} btf_source_args;

/* Loads spec as the input options say; on success warns on stderr ("btf CMD:
 * warning: ...") when images were interpolated. */
btf_result btf_source_load_args(const char *cmd, const char *spec, const btf_source_args *a, btf **out,
                                btf_error *err);

/* Opens spec as a view source (codec/include/btf_views.h) with the same options: an image
 * directory, a `.btf` file or gen:... BTF_ERR_UNSUPPORTED for what is only read
 * whole (a thesis package; --downsample of a .btf or gen:): load it instead. */
btf_result btf_source_open_views(const char *spec, const btf_source_args *a, btf_views *out, btf_error *err);
/* An input as a command reads it: view by view where it can (codec/include/btf_views.h),
 * else whole. Owned by the command, from btf_source_open to btf_source_close. */
typedef struct btf_source_input {
    btf *whole;      /* the BTF loaded whole, or NULL: read as views */
    btf_views views; /* the view source, or a wrap of whole */
} btf_source_input;

/* Opens spec as btf_source_open_views does unless whole (a command that reads it
 * several times) or it is only read whole (a thesis package, --downsample of a .btf):
 * then loads it (btf_source_load_args, its warnings under cmd) and wraps it, so that
 * in->views serves either way. */
btf_result btf_source_open(const char *cmd, const char *spec, const btf_source_args *a, int whole,
                           btf_source_input *in, btf_error *err);
/* After a command read in->views: the warnings of a source read as views (images
 * interpolated, clipped highlights); a loaded one warned when it loaded. */
void btf_source_warn_views(const char *cmd, const char *spec, const btf_source_input *in);
/* Releases what btf_source_open opened (nothing after a failed open). */
void btf_source_close(btf_source_input *in);
/* The warnings of a source once read: images interpolated, clipped highlights
 * (samples at 255: a count, the share and the worst file, when some image has at
 * least BTF_LOAD_CLIPPED_SHARE of them). */
void btf_source_warn(const char *cmd, const char *spec, int n_filled, int n_images, const btf_load_report *rep);

#endif
