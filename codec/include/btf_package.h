/* btf_package.h - the streamable package (doc/package-format.md): writer, reader,
 * CPU reference decoder.
 *
 *     btf_pca_options po = {0};  po.k = 3; po.components = 8;
 *     btf_package_options ko = {0};  ko.bits = 8;
 *     if (btf_package_compress(src, &po, &ko, "lib/wool", NULL, &err) != BTF_OK) ...
 *
 *     btf_package *p;
 *     btf_package_read("lib/wool", 2, &p, &err);        // first 2 chunks only
 *     btf_decode_options d = {0};                     // btf_decode.h  d.filter = BTF_FILTER_BILINEAR;
 *     float rgb[3];
 *     btf_decode(p, u, v, light_dir, view_dir, &d, rgb); // any direction
 *     btf_package_free(p);
 *
 * The writer builds the package in "OUT.tmp-<pid>" and renames it to OUT only
 * when every file and the manifest are written; on failure nothing named OUT
 * appears (an existing package OUT is left untouched).
 * Spatial levels are added to a written package by btf_lod_build (btf_lod.h);
 * the decoder is btf_decode.h.
 */
#ifndef BTF_PACKAGE_H
#define BTF_PACKAGE_H

#include <stdint.h>

#include "btf.h"
#include "btf_pca.h"
#include "btf_blocks.h"
#include "btf_metrics.h"

#ifdef __cplusplus
extern "C" {
#endif

#define BTF_PACKAGE_MAX_CHUNKS 1024
#define BTF_PACKAGE_MAX_FILES 8   /* files per chunk */
#define BTF_PACKAGE_NAME_MAX 64   /* file and material name length, including NUL */
#define BTF_PACKAGE_TEX_NOISE 0.5f /* default tex_noise (doc/package-format.md section 10.4) */
#define BTF_PACKAGE_THUMBNAIL_SIDE 128 /* longest side of the thumbnail.png `btf compress` writes */

/* Writer options; zero means default. Plain value. */
typedef struct btf_package_options {
    int bits;            /* texture bits per value: 8 (default) or 16 */
    const char *name;    /* material name in the manifest; NULL = last path element of OUT */
    int lab_max_texels;  /* texels in the Lab error subsample; 0 = 256 */
    /* 8-bit textures: quantisation step of component j in block b at least
     * tex_noise/255 * sqrt(12 * cols) / sigma_j, i.e. an RMS quantisation noise of
     * tex_noise (0..255 scale) per component in the decoded samples (equal noise per
     * component; minor components get fewer levels and compress better).
     * 0 = BTF_PACKAGE_TEX_NOISE; negative = always the full 8-bit range. */
    float tex_noise;
    /* 1: version 3 (doc/package-format.md section 10.8): per-component texture and
     * weight steps chosen by rate-distortion (codec/compress/btf_rd.h) for the same added
     * error as tex_noise's equal noise, weights deflated as wt-JJ.z. 8 bits only. */
    int rd;
    /* With rd: 1 = every texture a PNG; 0 = every texture a lossless WebP
     * (doc/package-format.md section 4). */
    int png_only;
    /* With rd (8 bits, not png_only): 1 (BTF_LOSSY_WEBP) = a component's texture may
     * also be a lossy WebP of its full-range codes, 2 (BTF_LOSSY_AVIF) an AVIF, at the
     * level the same rate-distortion choice picks where it costs fewer bytes for its
     * error than the lossless steps (doc/package-format.md sections 4.1 and 10.8;
     * codec/image/btf_lossy.h); 0 = lossless textures only. */
    int lossy;
    /* 1: spatial levels will be added to the package (btf_lod_compress): the budget
     * search, whose candidates' bytes leave the levels out, retries no runner-up.
     * (A lossy texture's rate is counted as it is: its coarse levels, matched to level
     * 0's error, cost no more than a lossless one's, doc/package-format.md section 10.7.) */
    int levels;
    /* > 0: the package gets thumbnail.png (btf_package_thumbnail) of at most this many
     * pixels a side, written into the package before it is renamed into place; 0 =
     * none. Never with estimate. */
    int thumbnail;
    /* 1: the package holds linear light (manifest "encoding": "linear",
     * doc/package-format.md section 3.7): every source value (byte/255 scale,
     * sRGB-encoded) goes through the exact sRGB EOTF (btf_color_srgb_decode) as it is
     * read, before the PCA. The chunks' "lab" and "delta_e76" are measured after
     * encoding back to sRGB (the source's scale, as for an sRGB package); "rmse",
     * "psnr" and "rmse_float" are on the package's own (linear) 0..255 scale.
     * 0: the source's values as they are ("srgb"). */
    int linear;
} btf_package_options;

#define BTF_LAP_PRED_N 6      /* weights per texel class */
#define BTF_LAP_PRED_MAX 4096 /* |w| bound a reader enforces */

/* Predictor of one residual level (a chunk's "predictor"). For each class of texel
 * in a 2x2 cell (0: even x and y, 1: odd x, even y, 2: even x, odd y), six integers
 * w, the texel predicted as
 *     p + floor((w0 eL + w1 eU + w2 eUR + w3 eUL + w4 D + w5) / 64)
 * p: the rounded 9-3-3-1 bilinear of the coarse texels around it (clamped to its
 * tile); eL, eU, eUR, eUL: q - p of its left, upper, upper-right and upper-left
 * neighbours (0 outside its tile); D: 4 coarse - the sum of p over its cell.
 * Plain value, embedded in btf_chunk_info. */
typedef struct btf_lap_pred {
    int w[3][BTF_LAP_PRED_N];
} btf_lap_pred;

/* One chunk of a package (manifest entry); owned by its btf_package. */
typedef struct btf_chunk_info {
    int component;
    int n_files;
    char files[BTF_PACKAGE_MAX_FILES][BTF_PACKAGE_NAME_MAX];
    long long bytes;
    double rmse, lab, psnr, delta_e76, rmse_float; /* after chunks 0..id have arrived */
    float *tex_range; /* n_blocks x {lo, step} (malloc'd) */
    float *wt_range;  /* n_blocks x {lo, step} (malloc'd) */
    int level;        /* spatial level (version 2, codec/include/btf_lod.h): texels are (W >> level) x (H >> level); 0 in version 1 */
    double contrib;   /* version 2: RMS (0..255) of this component's contribution seen at this level; 0 if absent */
    double wt8_step;  /* version 2: 8-bit weights are lo + wt8_step * step * q ("weights8_step"; 257 if absent) */
    double rmse_full; /* version 2: RMS (0..255) of what the prefix up to this chunk still lacks at level 0 */
    int has_pred;      /* version 4: the manifest lists "predictor" for this residual level */
    btf_lap_pred pred; /* version 4: the residual's predictor (btf_lap_pred_default when !has_pred) */
} btf_chunk_info;

/* A package read from disk (or just written); owned by the caller, btf_package_free. */
typedef struct btf_package {
    char name[BTF_PACKAGE_NAME_MAX];
    int width, height;
    btf_dirset lights, views;
    btf_blocks *blocks;
    int k, n_comp, bits;
    btf_center center;
    btf_grouping grouping;
    int atlas_cols, atlas_rows;
    int lab_stride;
    int n_chunks;           /* chunks listed in the manifest */
    btf_chunk_info *chunk;  /* n_chunks, importance order */
    int n_loaded;           /* chunks 0..n_loaded-1 have their data below */
    float **tex;            /* per loaded chunk: n_blocks * width * height dequantised texels, block-major */
    float **wt;             /* per loaded chunk: views * lights * 3 dequantised weights (of its component) */
    int version;            /* manifest version: 1, or 2 with spatial levels */
    int n_levels;           /* spatial levels (1 in version 1); level l has (W >> l) x (H >> l) texels */
    double lod_threshold;   /* version 2: visibility threshold the chunk order was made for ("lod"); 0 if absent */
    char *budget;           /* "budget": what btf_budget_compress chose and measured, as JSON text (malloc'd); NULL if none */
    struct btf_dirtab *dirtab[2]; /* lights, views as direction tables (btf_dirtab.h), made by btf_package_read (a list set's from the manifest's triangles; none with btf_package_read_options.no_dirtab), freed by btf_manifest_clear; NULL: btf_decode walks the rings */
    char *rd;               /* version 3 "rd": the steps btf_rd_allocate chose, as JSON text (malloc'd); NULL if none */
    uint8_t **q8;           /* version 4: per loaded chunk its level's reconstructed atlas bytes (malloc'd); NULL otherwise */
    uint8_t **w8q;          /* version 4: per loaded chunk that carried wt-JJ-8.png its bytes (malloc'd); NULL otherwise */
    int linear; /* "encoding": 1 linear light, 0 sRGB-encoded (default) */
} btf_package;

/* 1 when the package has spatial levels: version 2 (independent mips) or version 4
 * (finer levels as residuals over the coarser one, doc/package-format.md section 4.3). */
static inline int btf_package_has_levels(const btf_package *p)
{
    return p->version == 2 || p->version == 4;
}

/* Summary of a compression run (optional output of btf_package_compress). */
typedef struct btf_compress_stats {
    double seconds_pca;     /* block matrices + PCA + quantisation + error sums */
    double seconds_write;   /* files, ordering, Lab estimate, manifest */
    long long bytes;        /* all chunk files */
    int n_chunks;
    double rmse, lab, rmse_float; /* of the complete package */
} btf_compress_stats;

/* PCA + quantisation + ordering + files. src is not modified. */
btf_result btf_package_compress(const btf *src, const btf_pca_options *pca, const btf_package_options *opt,
                                const char *out_dir, btf_compress_stats *stats, btf_error *err);
/* The same from a view source (btf_views.h), one block of views in memory at a time:
 * the same package, byte for byte, as btf_package_compress on the BTF it reads.
 * Memory: the block matrix (4 * texels * 3 * lights * k bytes) plus the model
 * (4 * texels * C per block) and the atlases; docs in doc/package-format.md. */
btf_result btf_package_compress_views(btf_views *src, const btf_pca_options *pca, const btf_package_options *opt,
                                      const char *out_dir, btf_compress_stats *stats, btf_error *err);

/* The poster of the package dir (doc/package-format.md section 2): writes
 * dir/thumbnail.png (temporary file, fsync, rename) from btf_package_thumbnail_rgb
 * of the package read with every chunk. */
btf_result btf_package_thumbnail(const char *dir, int max_side, btf_error *err);
/* The material seen head-on as 8-bit sRGB RGB (*rgb malloc'd, *w x *h x 3, row 0
 * first; the caller frees it): every texel decoded by btf_decode from every loaded
 * chunk (nearest texel, level 0) at the light and the view nearest the normal (the
 * smallest theta of each set), then, when a side exceeds max_side, box-filtered
 * (btf_area_weights) to max_side on the longer side and the other in proportion
 * (at least 1), put on the source's scale (btf_package_to_source: a linear
 * package's pixels, averaged as radiance, are encoded to sRGB) and rounded by
 * btf_to_u8. */
btf_result btf_package_thumbnail_rgb(const btf_package *p, int max_side, int *w, int *h, uint8_t **rgb,
                                     btf_error *err);

/* Reads the manifest and the data of the first n chunks: n = 0 all (every file must
 * exist), n > 0 exactly the first n, n < 0 as many leading chunks as have their
 * files present (a partially received package). */
btf_result btf_package_read(const char *dir, int n, btf_package **out, btf_error *err);
/* btf_package_read with every file read through files (btf.h; NULL: the disk), e.g. a
 * package held in memory: the reader asks files for "DIR/manifest.json", "DIR/tex-00.png",
 * ... (dir only names them) and decodes PNG and WebP textures from the bytes it gets. */
btf_result btf_package_read_with(const char *dir, int n, const btf_files *files, btf_package **out, btf_error *err);
/* What btf_package_read_opts may skip; the caller's, read during the call only. */
typedef struct btf_package_read_options {
    int no_dirtab; /* 1: the reader builds no direction table (dirtab[] stay NULL but a list
                    * set's from the manifest's triangles): btf_decode then walks the rings
                    * (the same triangles, values equal within float rounding) */
} btf_package_read_options;
/* btf_package_read_with with options o (NULL or all zero: the same as it). The
 * measured samples (btf_package_value, btf_package_reconstruct) never read the tables. */
btf_result btf_package_read_opts(const char *dir, int n, const btf_files *files, const btf_package_read_options *o,
                                 btf_package **out, btf_error *err);
void btf_package_free(btf_package *p);

/* Decoded values (n floats in place) on the scale of the package's source: encoded
 * with the exact sRGB OETF (btf_color_srgb_encode) when p->linear, unchanged
 * otherwise. What every comparison with the source and every image goes through;
 * btf_decode returns the package's own values. */
void btf_package_to_source(const btf_package *p, float *v, size_t n);

/* Direct reconstruction of the source at a measured (view, light) pair and texel
 * from the first n loaded chunks (n <= 0 or n > n_loaded means all loaded), on the
 * source's scale (btf_package_to_source: sRGB-encoded for a linear package). */
void btf_package_value(const btf_package *p, int view, int light, int x, int y, int n, float rgb[3]);
/* Whole-BTF reconstruction (BTF_F32) of the source from the first n loaded chunks,
 * as btf_package_value. */
btf_result btf_package_reconstruct(const btf_package *p, int n, btf **out, btf_error *err);
/* The error of the first n loaded chunks (1..n_loaded) against ref (the source: same
 * size and direction sets) over every texel and (view, light) pair, as btf_compare
 * of btf_package_reconstruct's BTF gives it (btf eval's numbers), a tile of 1024
 * texels of one view in memory at a time on OpenMP's threads. */
btf_result btf_package_compare(const btf_package *p, int n, const btf *ref, btf_metrics *out, btf_error *err);
/* The same for count prefixes in one pass (out[i]: the first ns[i] chunks; count
 * 1..BTF_PACKAGE_COMPARE_MAX): the reference read and its Lab found once, the chunks
 * summed once up to the largest; each out[i] equals btf_package_compare's. */
#define BTF_PACKAGE_COMPARE_MAX 64
btf_result btf_package_compare_prefixes(const btf_package *p, const int *ns, int count, const btf *ref,
                                        btf_metrics *out, btf_error *err);
/* What a comparison measures; zero (or NULL) = the decoded floats. The caller's value. */
typedef struct btf_compare_options {
    int displayed; /* 1: each decoded value as the 8-bit code a display stores (btf_metrics_displayed) */
} btf_compare_options;
/* btf_package_compare_prefixes as o says. */
btf_result btf_package_compare_with(const btf_package *p, const int *ns, int count, const btf *ref,
                                    const btf_compare_options *o, btf_metrics *out, btf_error *err);

/* Index of the loaded chunk (among the first n; n <= 0: all loaded) of component c
 * whose level is closest to `level` from below (finer), else the coarsest loaded
 * level above it; -1 if c has no loaded chunk. */
int btf_package_chunk_at(const btf_package *p, int n, int component, int level);

/* Value of chunk i's texture in block b at level-0 texel (x, y): direct at level 0,
 * bilinear (clamped to the tile) at the texel centre otherwise. */
float btf_package_texel(const btf_package *p, int i, int b, int x, int y);

/* Dequantisation, the one formula every decoder uses (float32): lo + step * q. */
static inline float btf_package_dequant(const float range[2], unsigned q)
{
    return range[0] + range[1] * (float)q;
}

#ifdef __cplusplus
}
#endif
#endif
