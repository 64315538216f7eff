/* test_examples.c - room codec, suite "examples": the usage examples at the top of
 * the codec's headers, compiled and run as written there (only paths and inputs are filled in),
 * so an example that no longer matches the API fails to build. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "btf_base64.h"
#include "btf_color.h"
#include "btf_fs.h"
#include "btf_gen.h"
#include "btf_lod.h"
#include "btf_manifest.h"
#include "btf_package.h"
#include "btf_views.h"
#include "btf_rd.h"
#include "btf_wtz.h"
#include "fixtures.h"
#include "btf_decode.h"

/* A small generated material for the examples. */
static btf *example_source(void)
{
    return fx_material(BTF_GEN_KNIT, 16, NULL, 0);
}

/* codec/include/btf_package.h and codec/include/btf_lod.h */
Test(examples, package_and_lod_headers)
{
    char dir[64], wool[128], wool1[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(wool1, sizeof wool1, "%s/wool-v1", dir);
    snprintf(wool, sizeof wool, "%s/wool", dir);
    btf *src = example_source();
    btf_error err = {0};
    float u = 0.3f, v = 0.6f, light_dir[3] = {0.2f, 0.1f, 1.0f}, view_dir[3] = {-0.1f, 0.3f, 1.0f};
    /* btf_package.h */
    btf_pca_options po = {0};  po.k = 3; po.components = 8;
    btf_package_options ko = {0};  ko.bits = 8;
    if (btf_package_compress(src, &po, &ko, wool1, NULL, &err) != BTF_OK)
        cr_assert_fail("%s", err.msg);
    btf_package *p;
    btf_package_read(wool1, 2, &p, &err);        // first 2 chunks only
    btf_decode_options d = {0};  d.filter = BTF_FILTER_BILINEAR;
    float rgb[3];
    btf_decode(p, u, v, light_dir, view_dir, &d, rgb); // any direction
    cr_expect(isfinite(rgb[0]) && rgb[1] > 0.0f, "decoded %g %g %g", rgb[0], rgb[1], rgb[2]);
    cr_expect_eq(p->n_loaded, 2);
    /* btf_lod.h */
    btf_lod_options o = {0};  o.levels = 4;
    cr_assert_eq(btf_lod_build(wool1, wool, &o, NULL, &err), BTF_OK, "%s", err.msg);   // v1 -> v2 with mips
    btf_lod_view lv = {0};
    lv.texels_per_pixel = btf_lod_footprint(p->width, 1.0, 300.0); // 300-px thumbnail
    lv.threshold = BTF_LOD_THRESHOLD;
    btf_lod_selection s;
    btf_lod_select(p, &lv, &s, NULL);  // s.limit = chunks to ask the server for
    cr_expect_eq(s.limit, p->n_chunks, "a version-1 package needs every chunk");
    btf_package_free(p);
    btf_free(src);
    fx_rmtree(dir);
}

/* codec/common/btf_fs.h */
Test(examples, fs_header)
{
    char dir[64], wool[128], notes[160];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(wool, sizeof wool, "%s/wool", dir);
    snprintf(notes, sizeof notes, "%s/notes.txt", dir);
    btf *src = example_source();
    btf_error err = {0};
    btf_pca_options po = {0};
    po.k = 1, po.components = 2;
    cr_assert_eq(btf_package_compress(src, &po, NULL, wool, NULL, &err), BTF_OK, "%s", err.msg);
    char path[BTF_FS_PATH_MAX + 32];
    snprintf(path, sizeof path, "%s/manifest.json", wool);
    size_t n;
    char *text;
    if (btf_fs_read(path, 1 << 20, &text, &n, &err) != BTF_OK)
        cr_assert_fail("%s", err.msg); // NUL-terminated
    btf_fs_write_atomic(notes, text, n, &err);  // temp + fsync + rename + fsync dir
    cr_expect_eq(btf_fs_size(notes), (long long)n);
    char *png, *wt, file[BTF_FS_PATH_MAX + 32];
    size_t png_n, wt_n;
    snprintf(file, sizeof file, "%s/tex-00.png", wool);
    cr_assert_eq(btf_fs_read(file, 1 << 20, &png, &png_n, &err), BTF_OK, "%s", err.msg);
    snprintf(file, sizeof file, "%s/wt-00.bin", wool);
    cr_assert_eq(btf_fs_read(file, 1 << 20, &wt, &wt_n, &err), BTF_OK, "%s", err.msg);
    btf_package *p = NULL;
    btf_fs_mem_file f[3] = {{"manifest.json", text, n}, {"tex-00.png", png, png_n}, {"wt-00.bin", wt, wt_n}};
    btf_fs_mem m = {f, 3};
    btf_files files = btf_fs_mem_files(&m);               // a package's first chunk in memory
    btf_package_read_with("mem", 1, &files, &p, &err);    // reads "mem/manifest.json", ...
    cr_expect(p && p->n_loaded == 1, "%s", err.msg);
    btf_package_free(p);
    free(text), free(png), free(wt);
    char tmp[BTF_FS_PATH_MAX];
    btf_fs_temp_dir(wool, tmp, sizeof tmp, NULL, NULL, &err);   // "lib/wool.tmp-PID", made empty
    snprintf(path, sizeof path, "%s/manifest.json", tmp);
    btf_fs_write_atomic(path, "{}", 2, &err);
    /* the example's is_package: the manifest module's test of what out holds */
    cr_expect_eq(btf_fs_replace_dir(tmp, wool, btf_manifest_owns_dir, NULL, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(btf_fs_size(path), -1, "the temporary is still there");
    snprintf(path, sizeof path, "%s/manifest.json", wool);
    cr_expect_eq(btf_fs_size(path), 2, "the package was not swapped for the new tree");
    btf_free(src);
    fx_rmtree(dir);
}

/* codec/common/btf_base64.h, codec/common/btf_color.h, codec/format/btf_manifest.h */
Test(examples, base64_color_manifest_headers)
{
    uint8_t bytes[16];
    for (int i = 0; i < 16; i++)
        bytes[i] = (uint8_t)(i * 17);
    char *s = btf_base64_encode(bytes, 16);        // malloc'd, NUL-terminated
    uint8_t back[16];
    int ok = btf_base64_decode(s, back, 16);       // 1: exactly 16 bytes decoded
    free(s);
    cr_expect(ok && !memcmp(bytes, back, 16));

    float lab[3], rgb[3] = {0.5f, 0.25f, 1.0f};   // sRGB-encoded, 0..1
    btf_color_srgb_to_lab(rgb, lab);              // D65, L in 0..100
    double lin = btf_color_srgb_decode(0.5);      // 0.214...
    cr_expect(fabs(lin - 0.21404) < 1e-4, "%g", lin);
    cr_expect(lab[0] > 0.0f && lab[0] < 100.0f);

    char dir[64], pkg[128], path[200], *text = NULL;
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(pkg, sizeof pkg, "%s/p", dir);
    btf *src = example_source();
    btf_error err = {0};
    btf_pca_options po = {0};
    po.k = 1, po.components = 2;
    cr_assert_eq(btf_package_compress(src, &po, NULL, pkg, NULL, &err), BTF_OK, "%s", err.msg);
    snprintf(path, sizeof path, "%s/manifest.json", pkg);
    cr_assert_eq(btf_fs_read(path, BTF_MANIFEST_MAX_BYTES, &text, NULL, &err), BTF_OK);
    btf_package p = {0};
    if (btf_manifest_parse(text, path, &p, &err) == BTF_OK) {
        char *again = btf_manifest_print(&p, &err);   // same manifest, p.version decides
        cr_expect(again && strstr(again, "\"btf-package\""));
        free(again);
    }
    btf_manifest_clear(&p);
    free(text);
    btf_free(src);
    fx_rmtree(dir);
}

/* codec/include/btf_views.h */
Test(examples, views_header)
{
    char dir[64], path[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(path, sizeof path, "%s/dome", dir);
    btf *src = example_source();
    cr_assert_eq(btf_save_ubo2003_dir(src, path, "Knit", "png", NULL), BTF_OK);
    int view = 2;
    btf_load_options o = {0};
    o.sampling = &src->views; /* the example's NULL: a built-in sampling the names fit */
    btf_views s;
    btf_error err;
    if (btf_views_open(path, &o, &s, &err) != BTF_OK) puts(err.msg);  // images or .btf
    float *cols = malloc(btf_views_floats(&s) * sizeof(float));
    btf_views_fill(&s, view, cols, &err);   // cols[(light*3 + c) * texels + y*width + x]
    size_t texels = (size_t)s.width * s.height;
    cr_expect_eq(cols[(5 * 3 + 1) * texels + 3 * s.width + 4], btf_get(src, view, 5, 4, 3, 1));
    free(cols);
    btf_views_close(&s);
    btf_free(src);
    fx_rmtree(dir);
}

/* codec/compress/btf_rd.h and codec/format/btf_wtz.h */
Test(examples, rd_and_wtz_headers)
{
    btf *src = example_source();
    btf_error err = {0};
    btf_pca_options o = {0};
    btf_pca_model *model = NULL;
    cr_assert_eq(btf_pca_compress(src, &o, NULL, NULL, &model, &err), BTF_OK, "%s", err.msg);
    int cols = (int)ceil(sqrt((double)model->blocks->n_blocks)), rows = (model->blocks->n_blocks + cols - 1) / cols;
    /* btf_rd.h */
    btf_rd_params par = {model, cols, rows, 0.5f, 0, 0, NULL, 0.0, NULL, NULL, 8, 0, 0};  // equal-noise error, lossless WebP, every step measured
    btf_rd_result rr;
    if (btf_rd_allocate(&par, &rr, &err) == BTF_OK) {
        float g = rr.tex_noise[0], h = rr.wt_noise[0];   // component 0's noise multipliers
        cr_assert(g > 0.0f && h >= 0.0f);
        btf_rd_result_free(&rr);
    } else {
        cr_assert_fail("%s", err.msg);
    }
    /* btf_wtz.h */
    int V = src->views.n_dirs, L = src->lights.n_dirs;
    uint16_t *q = calloc((size_t)V * L * 3, sizeof *q), *q_back = calloc((size_t)V * L * 3, sizeof *q);
    for (int i = 0; i < V * L * 3; i++)
        q[i] = (uint16_t)(i * 37);
    uint8_t *z; size_t nz;
    btf_wtz_encode(q, V, L, &z, &nz, &err);       // q: V*L*3 values, (v*L + l)*3 + c
    btf_wtz_decode(z, nz, V, L, q_back, "wt-00.z", &err);
    free(z);
    cr_assert_eq(memcmp(q, q_back, (size_t)V * L * 3 * sizeof *q), 0);
    free(q), free(q_back);
    btf_pca_model_free(model);
    btf_free(src);
}
