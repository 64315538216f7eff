/* test_package.c - room codec, suite "package": the package writer and reader
 * (codec/include/btf_package.h) and the CPU reference decoder (btf_decode.h). */
#include <criterion/criterion.h>
#include <cjson/cJSON.h>
#include <dirent.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "btf_gen.h"
#include "btf_metrics.h"
#include "btf_package.h"
#include "fixtures.h"
#include "btf_decode.h"
#include "btf_compress.h"
#include "btf_lossy.h"

/* A generated knit material, size x size, on fx_dirs11 (8-bit like measured data). */
static btf *make_material(int size)
{
    btf_dirset d = fx_dirs11();
    return fx_gen(BTF_GEN_KNIT, size, &d, BTF_U8);
}

static void compress_ok(const btf *src, int k, int C, int bits, const char *out)
{
    btf_pca_options po = {0};
    po.k = k, po.components = C;
    btf_package_options ko = {0};
    ko.bits = bits;
    btf_error err = {0};
    cr_assert_eq(btf_package_compress(src, &po, &ko, out, NULL, &err), BTF_OK, "%s", err.msg);
}

/* Number of entries in dir other than . and .. */
static int count_entries(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d)
        return -1;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)))
        n += strcmp(e->d_name, ".") && strcmp(e->d_name, "..");
    closedir(d);
    return n;
}

Test(package, manifest_contract_and_sizes)
{
    char tmp[256], out[512];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(out, sizeof out, "%s/knit", tmp);
    btf *src = make_material(16);
    compress_ok(src, 3, 5, 8, out);
    char path[800];
    snprintf(path, sizeof path, "%s/manifest.json", out);
    FILE *f = fopen(path, "rb");
    cr_assert_not_null(f);
    char *text = calloc(1, 1 << 20);
    size_t n = fread(text, 1, (1 << 20) - 1, f);
    fclose(f);
    cr_assert_gt(n, 0);
    cJSON *m = cJSON_Parse(text);
    free(text);
    cr_assert_not_null(m);
    cr_assert_str_eq(cJSON_GetObjectItem(m, "format")->valuestring, "btf-package");
    cr_assert_eq(cJSON_GetObjectItem(m, "version")->valueint, 1);
    cr_assert_str_eq(cJSON_GetObjectItem(m, "name")->valuestring, "knit");
    const cJSON *chunks = cJSON_GetObjectItem(m, "chunks");
    cr_assert_eq(cJSON_GetArraySize(chunks), 5);
    int files_seen = 1; /* manifest.json */
    for (int i = 0; i < 5; i++) {
        const cJSON *c = cJSON_GetArrayItem(chunks, i);
        cr_assert_eq(cJSON_GetObjectItem(c, "id")->valueint, i);
        long long sum = 0;
        const cJSON *fl;
        cJSON_ArrayForEach(fl, cJSON_GetObjectItem(c, "files"))
        {
            const char *s = fl->valuestring;
            cr_assert_eq(strspn(s, "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789._-"), strlen(s));
            snprintf(path, sizeof path, "%s/%s", out, s);
            struct stat st;
            cr_assert_eq(stat(path, &st), 0, "%s", path);
            cr_assert(S_ISREG(st.st_mode));
            sum += st.st_size;
            files_seen++;
        }
        cr_assert_eq((long long)cJSON_GetObjectItem(c, "bytes")->valuedouble, sum);
        cr_assert(cJSON_IsNumber(cJSON_GetObjectItem(c, "rmse")) && cJSON_IsNumber(cJSON_GetObjectItem(c, "lab")));
    }
    cr_assert_eq(count_entries(out), files_seen, "only manifest and chunk files in the package");
    cr_assert_eq(count_entries(tmp), 1, "no temporary directory left beside the package");
    cJSON_Delete(m);
    btf_free(src);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

Test(package, error_curve_monotone_and_equal_to_direct_measurement)
{
    char tmp[256], out[512];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(out, sizeof out, "%s/knit", tmp);
    btf *src = make_material(16);
    compress_ok(src, 3, 6, 8, out);
    btf_package *p = fx_package(out, NULL, 0);
    cr_assert_eq(p->n_chunks, 6);
    cr_assert_eq(p->chunk[0].component, 0, "component 0 first: it renders alone");
    for (int n = 1; n <= p->n_chunks; n++) {
        const btf_chunk_info *c = &p->chunk[n - 1];
        if (n > 1)
            cr_assert_leq(c->rmse, p->chunk[n - 2].rmse, "chunk %d raises the error", n - 1);
        /* independent measurement: decode the whole BTF from n chunks and compare with btf_compare */
        btf *rec = NULL;
        btf_error err = {0};
        cr_assert_eq(btf_package_reconstruct(p, n, &rec, &err), BTF_OK, "%s", err.msg);
        btf_metrics mt;
        cr_assert_eq(btf_compare(src, rec, NULL, &mt, &err), BTF_OK, "%s", err.msg);
        /* the manifest's rmse comes from an exact double-precision identity, the check from
         * float sums: they agree to ~1e-6 relative; 16x16 <= 1024 texels, so the Lab
         * sample is every texel and must agree to float rounding as well */
        cr_assert_float_eq(c->rmse, mt.rmse, 1e-4 * mt.rmse + 1e-6, "chunk %d: %g vs %g", n - 1, c->rmse, mt.rmse);
        cr_assert_float_eq(c->lab, mt.lab_thesis, 1e-3 * mt.lab_thesis + 1e-6, "chunk %d", n - 1);
        cr_assert_leq(c->rmse_float, c->rmse + 1e-9, "quantisation cannot beat the float PCA here");
        /* the same measurement a view at a time: the same values, sums in another order */
        btf_metrics mv;
        cr_assert_eq(btf_package_compare(p, n, src, &mv, &err), BTF_OK, "%s", err.msg);
        cr_assert_float_eq(mv.lab_thesis, mt.lab_thesis, 1e-9 * mt.lab_thesis, "chunk %d", n - 1);
        cr_assert_float_eq(mv.rmse, mt.rmse, 1e-9 * mt.rmse, "chunk %d", n - 1);
        cr_assert_eq(mv.pixels, mt.pixels);
        btf_free(rec);
    }
    btf_metrics mv;
    btf_error err = {0};
    /* several prefixes in one pass, in any order, one twice: each as measured alone */
    int ns[5] = {6, 2, 4, 2, 1};
    btf_metrics mp[5];
    cr_assert_eq(btf_package_compare_prefixes(p, ns, 5, src, mp, &err), BTF_OK, "%s", err.msg);
    for (int i = 0; i < 5; i++) {
        cr_assert_eq(btf_package_compare(p, ns[i], src, &mv, &err), BTF_OK, "%s", err.msg);
        cr_expect_eq(mp[i].lab_thesis, mv.lab_thesis, "prefix %d: %.17g vs %.17g", ns[i], mp[i].lab_thesis, mv.lab_thesis);
        cr_expect_eq(mp[i].rmse, mv.rmse, "prefix %d", ns[i]);
        cr_expect_eq(mp[i].delta_e76, mv.delta_e76, "prefix %d", ns[i]);
    }
    cr_expect_neq(mp[0].lab_thesis, mp[1].lab_thesis, "6 chunks and 2 differ");
    int bad[2] = {1, p->n_loaded + 1};
    cr_expect_eq(btf_package_compare_prefixes(p, bad, 2, src, mp, &err), BTF_ERR_ARG, "one prefix too long");
    cr_expect_eq(btf_package_compare_prefixes(p, ns, 0, src, mp, &err), BTF_ERR_ARG, "no prefix");
    cr_expect_eq(btf_package_compare(p, 0, src, &mv, &err), BTF_ERR_ARG, "no chunk is refused");
    cr_expect_eq(btf_package_compare(p, p->n_loaded + 1, src, &mv, &err), BTF_ERR_ARG, "more than loaded");
    btf *other = make_material(8);
    cr_expect_eq(btf_package_compare(p, 1, other, &mv, &err), BTF_ERR_ARG, "another size");
    cr_expect(strstr(err.msg, "sizes differ"), "%s", err.msg);
    btf_free(other);
    btf_package_free(p);
    btf_free(src);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

/* Quantisation loss bound (doc/package-format.md): per sample |quantised - float| <=
 * sum_j ( dt_j |w_j| + |t_j| dw_j + dt_j dw_j ), dt = step_t/2, dw = step_w/2. */
static void check_quant_bound(int bits, double *loss_out)
{
    btf *src = make_material(16);
    char tmp[256], out[512];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(out, sizeof out, "%s/m", tmp);
    compress_ok(src, 3, 4, bits, out);
    btf_package *p = fx_package(out, NULL, 0);
    btf_pca_options po = {0};
    po.k = 3, po.components = 4;
    btf_pca_model *m = NULL;
    btf_error err = {0};
    cr_assert_eq(btf_pca_compress(src, &po, NULL, NULL, &m, &err), BTF_OK, "%s", err.msg);
    double worst = 0.0;
    for (int v = 0; v < 11; v++)
        for (int l = 0; l < 11; l++)
            for (int y = 0; y < 16; y++)
                for (int x = 0; x < 16; x++) {
                    float rgb[3];
                    btf_package_value(p, v, l, x, y, 0, rgb);
                    int b = m->blocks->block_of_view[v];
                    const btf_pca_block *k = &m->block[b];
                    int col0 = (m->blocks->pos_in_block[v] * 11 + l) * 3;
                    for (int c = 0; c < 3; c++) {
                        double bound = 1e-6; /* float rounding of the sums */
                        for (int a = 0; a < p->n_loaded; a++) {
                            int j = p->chunk[a].component;
                            double dt = 0.5 * p->chunk[a].tex_range[2 * b + 1], dw = 0.5 * p->chunk[a].wt_range[2 * b + 1];
                            double t = fabs(k->t[(size_t)j * k->rows + y * 16 + x]), w = fabs(k->w[(size_t)j * k->cols + col0 + c]);
                            bound += dt * w + t * dw + dt * dw + 1e-6 * (t * w);
                        }
                        double d = fabs(rgb[c] - btf_pca_model_value(m, v, l, x, y, c, 4));
                        cr_assert_leq(d, bound, "v %d l %d x %d y %d c %d: %g > %g", v, l, x, y, c, d, bound);
                        worst = d > worst ? d : worst;
                    }
                }
    *loss_out = p->chunk[p->n_chunks - 1].rmse - p->chunk[p->n_chunks - 1].rmse_float;
    btf_pca_model_free(m);
    btf_package_free(p);
    btf_free(src);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

Test(package, quantisation_loss_bounded)
{
    double loss8, loss16;
    check_quant_bound(8, &loss8);
    check_quant_bound(16, &loss16);
    cr_assert_geq(loss8, -1e-6);
    cr_assert_leq(fabs(loss16), loss8 + 1e-9, "16 bits lose no more than 8 bits");
}

Test(package, partial_package_reads_and_decodes)
{
    char tmp[256], out[512], path[800];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(out, sizeof out, "%s/m", tmp);
    btf *src = make_material(16);
    compress_ok(src, 3, 4, 8, out);
    btf_package *full = fx_package(out, NULL, 0), *two = fx_package(out, NULL, 2);
    cr_assert_eq(two->n_loaded, 2);
    /* remove the files of chunks 2 and 3: a client that received two chunks */
    for (int i = 2; i < full->n_chunks; i++)
        for (int f = 0; f < full->chunk[i].n_files; f++) {
            snprintf(path, sizeof path, "%s/%s", out, full->chunk[i].files[f]);
            cr_assert_eq(unlink(path), 0);
        }
    btf_package *part = fx_package(out, NULL, -1), *none = NULL;
    cr_assert_eq(part->n_loaded, 2);
    btf_error err = {0};
    cr_assert_neq(btf_package_read(out, 0, &none, &err), BTF_OK);
    cr_assert_null(none);
    cr_assert(strstr(err.msg, ".png") || strstr(err.msg, ".bin"), "names the missing file: %s", err.msg);
    float a[3], b[3], c[3], L[3] = {0.3f, 0.1f, 0.9f}, V[3] = {-0.2f, 0.4f, 0.8f};
    btf_decode_options o = {0};
    o.filter = BTF_FILTER_BILINEAR;
    btf_decode(part, 0.37f, 0.61f, L, V, &o, a);
    btf_decode(two, 0.37f, 0.61f, L, V, &o, b);
    o.n_chunks = 2;
    btf_decode(full, 0.37f, 0.61f, L, V, &o, c);
    for (int i = 0; i < 3; i++) {
        cr_assert_eq(a[i], b[i]);
        cr_assert_eq(a[i], c[i]);
    }
    btf_package_free(full), btf_package_free(two), btf_package_free(part);
    btf_free(src);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

Test(package, decoder_at_measured_directions_equals_direct_reconstruction)
{
    char tmp[256], out[512];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(out, sizeof out, "%s/m", tmp);
    btf *src = make_material(16);
    compress_ok(src, 3, 4, 8, out);
    btf_package *p = fx_package(out, NULL, 0);
    float dv[3], dl[3], got[3], want[3], w2[3];
    for (int v = 0; v < 11; v += 2)
        for (int l = 0; l < 11; l += 3) {
            btf_dirset_vector(&p->views, v, dv);
            btf_dirset_vector(&p->lights, l, dl);
            for (int y = 0; y < 16; y += 5)
                for (int x = 0; x < 16; x += 3) {
                    btf_package_value(p, v, l, x, y, 0, want);
                    for (int filt = 0; filt < 2; filt++) {
                        btf_decode_options o = {0};
                        o.filter = filt ? BTF_FILTER_BILINEAR : BTF_FILTER_NEAREST;
                        btf_decode(p, (x + 0.5f) / 16.0f, (y + 0.5f) / 16.0f, dl, dv, &o, got);
                        for (int c = 0; c < 3; c++) /* interpolation weights at a sample are 1 +- float rounding */
                            cr_assert_float_eq(got[c], want[c], 1e-4, "v %d l %d x %d y %d", v, l, x, y);
                    }
                    if (x + 1 < 16) { /* halfway between two texel centres: their mean */
                        btf_decode_options o = {0};
                        o.filter = BTF_FILTER_BILINEAR;
                        btf_package_value(p, v, l, x + 1, y, 0, w2);
                        btf_decode(p, (x + 1.0f) / 16.0f, (y + 0.5f) / 16.0f, dl, dv, &o, got);
                        for (int c = 0; c < 3; c++)
                            cr_assert_float_eq(got[c], 0.5f * (want[c] + w2[c]), 1e-4);
                    }
                }
        }
    /* never NaN: below the horizon, at the pole, absurd coordinates */
    float down[3] = {0.3f, 0.2f, -1.0f}, pole[3] = {0, 0, 1};
    btf_decode_options o = {0};
    o.filter = BTF_FILTER_BILINEAR;
    btf_decode(p, -3.0f, 7.5f, down, pole, &o, got);
    o.wrap = 1;
    btf_decode(p, 1e9f, -1e9f, pole, down, &o, want);
    for (int c = 0; c < 3; c++)
        cr_assert(isfinite(got[c]) && isfinite(want[c]));
    btf_package_free(p);
    btf_free(src);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

/* btf_package_read_options.no_dirtab: the package reads without direction tables
 * (the option is not ignored), the measured samples are the same bits, and the
 * decoder's ring walk gives what the tables give within float rounding, at random
 * directions over the whole sphere (below the horizon too). */
Test(package, read_without_dirtabs_decodes_the_same)
{
    char tmp[256], out[512];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(out, sizeof out, "%s/m", tmp);
    btf *src = make_material(8);
    compress_ok(src, 3, 4, 8, out);
    btf_package *t = fx_package(out, NULL, 0), *r = NULL;
    btf_package_read_options ro = {0};
    ro.no_dirtab = 1;
    btf_error err = {0};
    cr_assert_eq(btf_package_read_opts(out, 0, NULL, &ro, &r, &err), BTF_OK, "%s", err.msg);
    cr_assert(t->dirtab[0] && t->dirtab[1], "the default read builds both tables");
    cr_assert(!r->dirtab[0] && !r->dirtab[1], "no_dirtab ignored");
    float a[3], b[3], L[3], V[3];
    for (int v = 0; v < 11; v++)
        for (int l = 0; l < 11; l++) {
            btf_package_value(t, v, l, v % 8, l % 8, 0, a);
            btf_package_value(r, v, l, v % 8, l % 8, 0, b);
            cr_assert(!memcmp(a, b, sizeof a), "view %d light %d", v, l);
        }
    uint32_t s = 12345u;
    btf_decode_options o = {0};
    o.filter = BTF_FILTER_BILINEAR;
    for (int i = 0; i < 2000; i++) {
        for (int c = 0; c < 3; c++)
            L[c] = 2.0f * (float)fx_unit(fx_xorshift32(&s)) - 1.0f, V[c] = 2.0f * (float)fx_unit(fx_xorshift32(&s)) - 1.0f;
        float u = (float)fx_unit(fx_xorshift32(&s)), w = (float)fx_unit(fx_xorshift32(&s));
        btf_decode(t, u, w, L, V, &o, a);
        btf_decode(r, u, w, L, V, &o, b);
        for (int c = 0; c < 3; c++)
            cr_assert(fabsf(a[c] - b[c]) <= 1e-4f * fmaxf(1.0f, fabsf(a[c])), "query %d: table %g, ring walk %g", i,
                      a[c], b[c]);
    }
    btf_package_free(t), btf_package_free(r);
    btf_free(src);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

/* Failing writer hook: fails when asked for file number *ctx. */
static int fail_nth(void *ctx, int i, const char *file)
{
    (void)file;
    return i == *(int *)ctx;
}

/* Records which OpenMP thread asked for each file; fails file *fail (-1: none). */
typedef struct thread_log {
    int fail;
    int thread[64]; /* by file number; one writer each */
} thread_log;

static int log_thread(void *ctx, int i, const char *file)
{
    (void)file;
    thread_log *t = ctx;
    if (i >= 0 && i < 64)
        t->thread[i] = omp_get_thread_num();
    return i == t->fail;
}

/* btf_package_compress on one OpenMP thread, the thread count restored afterwards. */
static void compress_one_thread(const btf *src, const btf_pca_options *po, const btf_package_options *ko,
                                const char *dir)
{
    int threads = omp_get_max_threads();
    btf_error err = {0};
    omp_set_num_threads(1);
    btf_result r = btf_package_compress(src, po, ko, dir, NULL, &err);
    omp_set_num_threads(threads);
    cr_assert_eq(r, BTF_OK, "%s", err.msg);
}

/* At least two OpenMP threads for the tests of threaded code, whatever
 * OMP_NUM_THREADS says (make test runs the suites on one thread each: two test
 * processes already keep both cores busy). */
static void at_least_two_threads(void)
{
    if (omp_get_max_threads() < 2)
        omp_set_num_threads(2);
}

/* Above BTF_METRICS_THREAD_MIN_PIXELS pixel pairs (20 prefixes x 225 directions
 * pairs x 256 texels = 1.15 M) the error curve's prefixes are measured on OpenMP's
 * threads: every chunk's errors the same as on one thread, bit for bit. */
Test(package, threaded_error_curve_matches_one_thread)
{
    static const btf_ring r[3] = {{0.0f, 1, 0.0f}, {30.0f, 6, 0.0f}, {60.0f, 8, 0.0f}};
    char tmp[256], a[512], b[512];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(a, sizeof a, "%s/a", tmp);
    snprintf(b, sizeof b, "%s/b", tmp);
    at_least_two_threads();
    btf *src = fx_material(BTF_GEN_TILES, 16, r, 3);
    btf_pca_options po = {0};
    po.k = 3, po.components = 20;
    btf_package_options ko = {0};
    ko.name = "m";
    cr_assert_geq((size_t)po.components * 15 * 15 * 256, BTF_METRICS_THREAD_MIN_PIXELS);
    btf_error err = {0};
    cr_assert_eq(btf_package_compress(src, &po, &ko, a, NULL, &err), BTF_OK, "%s", err.msg);
    compress_one_thread(src, &po, &ko, b);
    cr_expect(fx_same_file(a, b, "manifest.json"), "the error curve differs between 1 and %d threads",
              omp_get_max_threads());
    btf_free(src);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

/* Above the writer's threshold (1 MiB of atlases: 9 tiles of 96x96 texels at k = 1,
 * 16 components, 1.3 MiB) the component files are written on OpenMP's threads: the
 * same bytes as on one thread, and a failing file's own error. */
Test(package, threaded_writes_match_one_thread)
{
    char tmp[256], a[512], b[512];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(a, sizeof a, "%s/a", tmp);
    snprintf(b, sizeof b, "%s/b", tmp);
    at_least_two_threads();
    btf *src = fx_material(BTF_GEN_KNIT, 96, NULL, 0); /* 7 directions */
    btf_pca_options po = {0};
    po.k = 1, po.components = 16;
    thread_log tl = {.fail = -1};
    btf_package_options ko = {0};
    ko.name = "m"; /* one name: the manifests compare */
    btf_package_channel ch = {0};
    ch.write_hook = log_thread, ch.hook_ctx = &tl;
    btf_package_options kb = {0};
    kb.name = "m";
    btf_error err = {0};
    cr_assert_eq(btf_package_compress_with(src, &po, &ko, &ch, a, NULL, &err), BTF_OK, "%s", err.msg);
    int other = 0;
    for (int i = 0; i < 32; i++)
        other |= tl.thread[i] != 0;
    cr_expect(other, "every file was written by thread 0 (%d threads)", omp_get_max_threads());
    int threads = omp_get_max_threads();
    compress_one_thread(src, &po, &kb, b);
    DIR *d = opendir(a);
    int files = 0;
    for (struct dirent *e; d && (e = readdir(d));)
        if (e->d_name[0] != '.') {
            cr_expect(fx_same_file(a, b, e->d_name), "%s differs between 1 and %d threads", e->d_name, threads);
            files++;
        }
    if (d)
        closedir(d);
    cr_assert_eq(files, 33, "16 textures, 16 weights and the manifest");
    /* the weights of component 7 (file 15) fail: that file's error, the old package kept */
    tl.fail = 15;
    cr_assert_eq(btf_package_compress_with(src, &po, &ko, &ch, a, NULL, &err), BTF_ERR_IO);
    cr_expect(strstr(err.msg, "wt-07.bin: write failed"), "%s", err.msg);
    cr_assert_eq(count_entries(tmp), 2, "a temporary directory was left beside the packages");
    btf_free(src);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

/* A sink that refuses the file named *ctx, else puts it in the btf_fs_memdir. */
typedef struct refusing_sink {
    btf_fs_memdir dir;
    const char *refuse;
} refusing_sink;

static btf_result refuse_one(void *user, const char *name, const void *data, size_t n, btf_error *err)
{
    refusing_sink *s = user;
    if (s->refuse && !strcmp(name, s->refuse)) {
        snprintf(err->msg, sizeof err->msg, "%s: refused by the sink", name);
        return BTF_ERR_IO;
    }
    return btf_fs_memdir_put(&s->dir, name, data, n, err);
}

/* Compresses src with ko into the sink and into tmp/disk; every file the sink got is
 * the disk's, byte for byte, the disk has no other but its thumbnail, the sink's
 * package reads, and the out_dir it was given was never made. */
static void sink_matches_disk(const btf *src, const btf_pca_options *po, const btf_package_options *ko,
                              const char *tmp)
{
    char disk[512], never[512];
    snprintf(disk, sizeof disk, "%s/disk", tmp);
    snprintf(never, sizeof never, "%s/never", tmp);
    btf_error err = {0};
    cr_assert_eq(btf_package_compress(src, po, ko, disk, NULL, &err), BTF_OK, "%s", err.msg);
    refusing_sink s = {0};
    btf_package_channel ch = {0};
    ch.sink = refuse_one, ch.sink_user = &s;
    cr_assert_eq(btf_package_compress_with(src, po, ko, &ch, never, NULL, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(btf_fs_size(never), -1);
    cr_expect_eq(count_entries(never), -1, "the sink's out_dir was made");
    for (int i = 0; i < s.dir.mem.n; i++) {
        const btf_fs_mem_file *f = &s.dir.mem.file[i];
        char path[1024], *bytes = NULL;
        size_t n = 0;
        snprintf(path, sizeof path, "%s/%s", disk, f->name);
        cr_assert_eq(btf_fs_read(path, 1 << 26, &bytes, &n, &err), BTF_OK, "%s", err.msg);
        cr_expect(n == f->size && !memcmp(bytes, f->data, n), "%s: the sink's bytes differ from the disk's", f->name);
        free(bytes);
    }
    cr_expect_eq(s.dir.mem.n + (ko->thumbnail > 0), count_entries(disk), "a file only on the disk");
    btf_files files = btf_fs_mem_files(&s.dir.mem);
    btf_package *p = NULL;
    cr_assert_eq(btf_package_read_with("mem/m", 0, &files, &p, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(p->n_chunks, po->components);
    btf_package_free(p);
    s.refuse = "manifest.json"; /* a sink's error is the writer's */
    cr_expect_eq(btf_package_compress_with(src, po, ko, &ch, never, NULL, &err), BTF_ERR_IO);
    cr_expect(strstr(err.msg, "refused by the sink"), "%s", err.msg);
    btf_fs_memdir_free(&s.dir);
    cr_expect_eq(count_entries(tmp), 1, "only the disk's package in %s", tmp);
    cr_assert_eq(fx_rmtree(disk), 0);
}

/* btf_package_channel.sink: the package version 1 (16-bit textures) and version 3
 * (rate-distortion steps, lossy WebP allowed, a thumbnail asked for) held in memory. */
Test(package, sink_gets_the_files_the_disk_gets)
{
    char tmp[256];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    btf *src = make_material(16);
    btf_pca_options po = {0};
    po.k = 3, po.components = 4;
    btf_package_options ko = {0};
    ko.name = "m", ko.bits = 16;
    sink_matches_disk(src, &po, &ko, tmp);
    btf_package_options k3 = {0};
    k3.name = "m", k3.rd = 1, k3.lossy = BTF_LOSSY_WEBP, k3.thumbnail = 32;
    sink_matches_disk(src, &po, &k3, tmp);
    btf_free(src);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

Test(package, failing_writer_leaves_no_package)
{
    char tmp[256], out[512];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(out, sizeof out, "%s/m", tmp);
    btf *src = make_material(8);
    btf_pca_options po = {0};
    po.k = 3, po.components = 3;
    int fail_at[] = {0, 3, 6}; /* first texture, a weights file, the manifest (3 chunks = 6 files + manifest) */
    for (int i = 0; i < 3; i++) {
        btf_package_channel ch = {0};
        ch.write_hook = fail_nth;
        ch.hook_ctx = &fail_at[i];
        btf_error err = {0};
        cr_assert_eq(btf_package_compress_with(src, &po, NULL, &ch, out, NULL, &err), BTF_ERR_IO, "file %d", fail_at[i]);
        cr_assert(strstr(err.msg, "write failed"), "%s", err.msg);
        cr_assert_eq(count_entries(tmp), 0, "file %d: something was left in %s", fail_at[i], tmp);
    }
    /* an existing package survives a failed rewrite */
    compress_ok(src, 3, 3, 8, out);
    btf_package_channel ch = {0};
    int manifest_of_two = 4; /* 2 chunks = 4 files, then the manifest */
    ch.write_hook = fail_nth;
    ch.hook_ctx = &manifest_of_two;
    btf_error err = {0};
    po.components = 2;
    cr_assert_eq(btf_package_compress_with(src, &po, NULL, &ch, out, NULL, &err), BTF_ERR_IO);
    btf_package *p = fx_package(out, NULL, 0);
    cr_assert_eq(p->n_chunks, 3);
    btf_package_free(p);
    cr_assert_eq(count_entries(tmp), 1);
    /* ... and a successful rewrite replaces it */
    compress_ok(src, 3, 2, 8, out);
    p = fx_package(out, NULL, 0);
    cr_assert_eq(p->n_chunks, 2);
    btf_package_free(p);
    cr_assert_eq(count_entries(tmp), 1);
    /* nonexistent parent directory */
    cr_assert_eq(btf_package_compress(src, &po, NULL, "/nonexistent-btf-dir/sub/m", NULL, &err), BTF_ERR_IO);
    cr_assert(strstr(err.msg, "nonexistent-btf-dir"), "%s", err.msg);
    btf_free(src);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

Test(package, bad_inputs_refused)
{
    char tmp[256], out[512], path[800];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(out, sizeof out, "%s/m", tmp);
    btf *src = make_material(8);
    btf_pca_options po = {0};
    btf_package_options ko = {0};
    btf_error err = {0};
    ko.bits = 12;
    cr_assert_eq(btf_package_compress(src, &po, &ko, out, NULL, &err), BTF_ERR_ARG);
    ko.bits = 8;
    po.k = 0, po.components = 1000; /* more than 8x8 texels */
    cr_assert_eq(btf_package_compress(src, &po, &ko, out, NULL, &err), BTF_ERR_RANGE);
    ko.name = "../evil";
    po.components = 2;
    cr_assert_eq(btf_package_compress(src, &po, &ko, out, NULL, &err), BTF_ERR_ARG);
    ko.name = NULL;
    btf *nan = NULL;
    cr_assert_eq(btf_create(8, 8, &src->lights, &src->views, BTF_F32, &nan, &err), BTF_OK);
    ((float *)nan->data)[17] = NAN;
    cr_assert_eq(btf_package_compress(nan, &po, &ko, out, NULL, &err), BTF_ERR_NUMERIC);
    cr_assert_eq(count_entries(tmp), 0);
    /* damaged packages */
    compress_ok(src, 3, 2, 8, out);
    btf_package *p = NULL;
    snprintf(path, sizeof path, "%s/wt-01.bin", out);
    cr_assert_eq(truncate(path, 100), 0);
    cr_assert_eq(btf_package_read(out, 0, &p, &err), BTF_ERR_FORMAT);
    cr_assert(strstr(err.msg, "wt-01.bin"), "%s", err.msg);
    snprintf(path, sizeof path, "%s/manifest.json", out);
    const char *bad[] = {"{\"format\":\"btf-package\",\"version\":2}", "{\"format\":\"other\"}", "[1,2", "",
                         "{\"format\":\"btf-package\",\"version\":1,\"width\":99999,\"height\":8}"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        fx_write_text(path, bad[i]);
        cr_assert_neq(btf_package_read(out, 0, &p, &err), BTF_OK, "manifest %zu", i);
        cr_assert_null(p);
        cr_assert(strstr(err.msg, "manifest.json"), "%s", err.msg);
    }
    cr_assert_eq(btf_package_read("/nonexistent-btf-dir", 0, &p, &err), BTF_ERR_MISSING);
    btf_free(nan);
    btf_free(src);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

Test(package, constant_material_exact_and_finite)
{
    char tmp[256], out[512];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(out, sizeof out, "%s/c", tmp);
    btf *src = make_material(8);
    memset(src->data, 128, src->count); /* constant grey: rank 1 in every block */
    compress_ok(src, 3, 4, 8, out);
    btf_package *p = fx_package(out, NULL, 0);
    for (int i = 0; i < p->n_chunks; i++)
        cr_assert(isfinite(p->chunk[i].rmse) && isfinite(p->chunk[i].lab));
    /* one dominant component; quantisation of a constant texture is exact (step 0),
     * the weights cost at most half a 16-bit step: < 1e-4 of full scale */
    cr_assert_lt(p->chunk[p->n_chunks - 1].rmse, 0.05);
    float rgb[3];
    btf_package_value(p, 4, 7, 3, 5, 0, rgb);
    for (int c = 0; c < 3; c++)
        cr_assert_float_eq(rgb[c], 128.0f / 255.0f, 2e-4);
    btf_package_free(p);
    btf_free(src);
    cr_assert_eq(fx_rmtree(tmp), 0);
}
