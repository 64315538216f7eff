/* fuzz_roundtrip.c - libFuzzer round-trip target: the input chooses a tiny BTF
 * (1..4 x 1..4 texels, 1..3 rings of 1..4 directions for lights and views, the
 * samples), k, C (1..4) and the texture bits; it is compressed into a package held
 * in memory (the writer's sink, btf_package_channel.sink, into a btf_fs_memdir: no
 * file system call), read back through btf_files and every sample decoded. The
 * reader builds no direction tables (btf_package_read_options.no_dirtab): the
 * measured samples never read them and their build was a third of the time;
 * fuzz_dirset builds ring sets' tables (btf_dirtab_build), fuzz_package and
 * fuzz_package_mem those of the packages they read. Each decoded sample must match the float PCA
 * reconstruction within what quantisation can move it: per component j of block b,
 * |w_j| * tex_step/2 + |t_j| * wt_step/2 + tex_step * wt_step/4 (largest |t_j|,
 * |w_j| of the block), summed over components, plus float slack.
 * The material is kept this small because the work of an input grows with texels x
 * lights x views x components (the Lab error, the PNG encodings, the check of every
 * sample) while the paths it takes do not (the Lab error's texel subsampling starts
 * above 256 texels, beyond the 8 x 8 of the earlier bounds too): a few milliseconds
 * an input under the sanitizers, where an 8 x 8 material of 19 x 19 directions and
 * six components, within the earlier bounds, took 150. */
#include <math.h>

#include "btf_compress.h"
#include "btf_fs.h"
#include "btf_package.h"
#include "fuzz_util.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* Input bytes, read in order, cycling. */
typedef struct fuzz_bytes {
    const uint8_t *d;
    size_t n, at;
} fuzz_bytes;

static unsigned next_byte(fuzz_bytes *b)
{
    return b->n ? b->d[b->at++ % b->n] : 0u;
}

/* 1..3 rings with ascending theta and 1..4 directions each. */
static int make_rings(fuzz_bytes *in, btf_dirset *d)
{
    btf_ring r[3];
    int n = 1 + (int)(next_byte(in) % 3);
    float theta = (next_byte(in) & 1) ? 0.0f : 5.0f;
    for (int i = 0; i < n; i++) {
        r[i].theta_deg = theta;
        r[i].count = theta == 0.0f ? 1 : 1 + (int)(next_byte(in) % 4);
        r[i].phi_offset_deg = (float)(next_byte(in) % 60);
        theta += 10.0f + (float)(next_byte(in) % 30);
    }
    return btf_dirset_make(r, n, d, NULL) == BTF_OK;
}

/* Largest |x| of column j (n rows, column-major, ld = n). */
static double col_max(const float *a, int n, int j)
{
    double m = 0.0;
    for (int i = 0; i < n; i++)
        m = fmax(m, fabs((double)a[(size_t)j * n + i]));
    return m;
}

/* The quantisation bound of block b (see the file comment). */
static double block_bound(const btf_package *p, const btf_pca_block *blk, int b)
{
    double e = 0.0;
    for (int i = 0; i < p->n_chunks; i++) {
        int j = p->chunk[i].component;
        double ts = p->chunk[i].tex_range[2 * b + 1], ws = p->chunk[i].wt_range[2 * b + 1];
        e += col_max(blk->w, blk->cols, j) * ts / 2 + col_max(blk->t, blk->rows, j) * ws / 2 + ts * ws / 4;
    }
    return e;
}

static void check_package(const btf *src, const btf_pca_options *po, const btf_fs_memdir *md)
{
    btf_package *p = NULL;
    btf_pca_model *m = NULL;
    btf_error err = {{0}};
    btf_files files = btf_fs_mem_files(&md->mem);
    btf_package_read_options ro = {0};
    ro.no_dirtab = 1;
    FUZZ_CHECK(btf_package_read_opts("mem/rt", 0, &files, &ro, &p, &err) == BTF_OK);
    FUZZ_CHECK(!p->dirtab[0] && !p->dirtab[1]);
    FUZZ_CHECK(btf_pca_compress(src, po, NULL, NULL, &m, &err) == BTF_OK);
    for (int v = 0; v < src->views.n_dirs; v++) {
        int b = p->blocks->block_of_view[v];
        double bound = block_bound(p, &m->block[b], b) + 1e-4;
        for (int l = 0; l < src->lights.n_dirs; l++)
            for (int y = 0; y < src->height; y++)
                for (int x = 0; x < src->width; x++) {
                    float rgb[3];
                    btf_package_value(p, v, l, x, y, 0, rgb);
                    for (int c = 0; c < 3; c++) {
                        double f = btf_pca_model_value(m, v, l, x, y, c, m->n_comp);
                        if (!(fabs(rgb[c] - f) <= bound))
                            fprintf(stderr, "fuzz: view %d light %d texel %d,%d: %g vs float %g (bound %g)\n", v, l, x,
                                    y, rgb[c], f, bound);
                        FUZZ_CHECK(fabs(rgb[c] - f) <= bound);
                    }
                }
    }
    btf_pca_model_free(m);
    btf_package_free(p);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_bytes in = {data, size, 0};
    btf_dirset lights, views;
    int W = 1 + (int)(next_byte(&in) % 4), H = 1 + (int)(next_byte(&in) % 4);
    if (!make_rings(&in, &lights) || !make_rings(&in, &views))
        return 0;
    btf *src = NULL;
    if (btf_create(W, H, &lights, &views, BTF_U8, &src, NULL) != BTF_OK)
        return 0;
    size_t n = (size_t)views.n_dirs * lights.n_dirs * btf_image_samples(src);
    for (size_t i = 0; i < n; i++)
        ((uint8_t *)src->data)[i] = (uint8_t)next_byte(&in);
    btf_pca_options po = {0};
    po.k = 1 + (int)(next_byte(&in) % (unsigned)views.n_dirs);
    po.components = 1 + (int)(next_byte(&in) % 4);
    btf_package_options ko = {0};
    ko.bits = (next_byte(&in) & 1) ? 16 : 8;
    btf_fs_memdir md = {0};
    btf_package_channel ch = {0};
    ch.sink = btf_fs_memdir_put, ch.sink_user = &md;
    btf_error err = {{0}};
    if (btf_package_compress_with(src, &po, &ko, &ch, "mem/rt", NULL, &err) == BTF_OK)
        check_package(src, &po, &md);
    else
        FUZZ_CHECK(err.msg[0] != 0);
    btf_fs_memdir_free(&md);
    btf_free(src);
    return 0;
}
