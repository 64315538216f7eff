/* test_lod.c - room codec, suite "lod": spatial levels (package version 2),
 * level-aware decoding and the scene-driven chunk selection (codec/include/btf_lod.h). */
#include <criterion/criterion.h>
#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "btf_gen.h"
#include "btf_lod.h"
#include "btf_package.h"
#include "fixtures.h"
#include "btf_decode.h"

#define SIZE 32
#define COMPS 5
#define LEVELS 3

/* v1 package of a generated knit (SIZE^2, fx_dirs11: 11 x 11 directions) in dir/v1 and
 * its version 2 with LEVELS levels in dir/v2. */
static void make_packages(char *dir, size_t n, btf_lod_stats *st)
{
    btf_dirset d = fx_dirs11();
    fx_levels_spec spec = {.kind = BTF_GEN_KNIT, .size = SIZE, .storage = BTF_U8, .dirs = &d, .k = 3,
                           .components = COMPS, .levels = LEVELS};
    fx_levels(dir, n, &spec, st);
}

/* Field `key` of chunk i in dir/sub/manifest.json (read independently of the reader). */
static double manifest_num(const char *dir, const char *sub, int i, const char *key)
{
    char path[600];
    snprintf(path, sizeof path, "%s/%s/manifest.json", dir, sub);
    FILE *f = fopen(path, "rb");
    cr_assert(f);
    static char text[1 << 20];
    size_t n = fread(text, 1, sizeof text - 1, f);
    fclose(f);
    text[n] = 0;
    cJSON *m = cJSON_Parse(text);
    cr_assert(m);
    cJSON *v = cJSON_GetObjectItem(cJSON_GetArrayItem(cJSON_GetObjectItem(m, "chunks"), i), key);
    cr_assert(cJSON_IsNumber(v), "chunk %d has no %s", i, key);
    double x = v->valuedouble;
    cJSON_Delete(m);
    return x;
}

Test(lod, chunks_are_component_level_pairs_coarse_first)
{
    char dir[256];
    btf_lod_stats st;
    make_packages(dir, sizeof dir, &st);
    btf_package *p1 = fx_package(dir, "v1", 0), *p = fx_package(dir, "v2", 0);
    cr_assert_eq(p->version, 2);
    cr_assert_eq(p->n_levels, LEVELS);
    cr_assert_eq(p->n_chunks, COMPS * LEVELS);
    cr_assert_eq(st.n_chunks, COMPS * LEVELS);
    int seen[COMPS][LEVELS] = {{0}}, finest[COMPS];
    for (int c = 0; c < COMPS; c++)
        finest[c] = LEVELS;
    for (int i = 0; i < p->n_chunks; i++) {
        int c = p->chunk[i].component, l = p->chunk[i].level;
        cr_assert_eq(seen[c][l]++, 0, "chunk %d repeats (%d, %d)", i, c, l);
        cr_assert_eq(l, finest[c] - 1, "chunk %d: component %d level %d is not the next finer one", i, c, l);
        finest[c] = l;
        const char *last = p->chunk[i].files[p->chunk[i].n_files - 1];
        int w8 = p->chunk[i].n_files == 2 && strstr(last, "-8.png") != NULL;
        int w16 = p->chunk[i].n_files == 2 && strstr(last, ".bin") != NULL;
        cr_assert_eq(w8, l == LEVELS - 1, "chunk %d: 8-bit weights travel with the coarsest level only", i);
        cr_assert_eq(w16, l == 0, "chunk %d: 16-bit weights travel with level 0 only", i);
        if (i > 0)
            cr_assert_leq(p->chunk[i].rmse, p->chunk[i - 1].rmse + 1e-3, "chunk %d raises the error", i);
    }
    cr_assert_eq(p->chunk[0].component, p1->chunk[0].component, "chunk 0 = v1's first component");
    cr_assert_eq(p->chunk[0].level, LEVELS - 1, "chunk 0 at the coarsest level");
    /* the complete v2 package is the v1 package: same final error, same bytes + the coarse levels */
    cr_assert_float_eq(p->chunk[p->n_chunks - 1].rmse, p1->chunk[p1->n_chunks - 1].rmse, 1e-3);
    cr_assert_gt(st.bytes, st.bytes_v1);
    cr_assert_lt(st.first_chunk, p1->chunk[0].bytes, "coarse first chunk is smaller than v1's");
    btf_package_free(p1);
    btf_package_free(p);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* Level l texels are 2^l x 2^l means of level 0 (v1 dequantised) within half a step. */
Test(lod, levels_are_box_means)
{
    char dir[256];
    make_packages(dir, sizeof dir, NULL);
    btf_package *p1 = fx_package(dir, "v1", 0), *p = fx_package(dir, "v2", 0);
    int nb = p->blocks->n_blocks;
    for (int i = 0; i < p->n_chunks; i++) {
        int c = p->chunk[i].component, l = p->chunk[i].level, s = 1 << l, w = SIZE >> l;
        int a = 0;
        while (p1->chunk[a].component != c)
            a++;
        for (int b = 0; b < nb; b++) {
            float half = 0.5f * p->chunk[i].tex_range[2 * b + 1] + 1e-5f;
            for (int y = 0; y < w; y++)
                for (int x = 0; x < w; x++) {
                    double m = 0.0;
                    for (int yy = 0; yy < s; yy++)
                        for (int xx = 0; xx < s; xx++)
                            m += p1->tex[a][((size_t)b * SIZE + y * s + yy) * SIZE + x * s + xx];
                    m /= (double)s * s;
                    float got = p->tex[i][((size_t)b * w + y) * w + x];
                    cr_assert_leq(fabs(got - m), half, "chunk %d block %d texel (%d,%d): %g vs mean %g", i, b, x, y,
                                  got, m);
                }
        }
    }
    btf_package_free(p1);
    btf_package_free(p);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* rmse_full of every prefix against a brute-force reconstruction (btf_package_value). */
Test(lod, prefix_errors_match_reconstruction)
{
    char dir[256];
    make_packages(dir, sizeof dir, NULL);
    btf_package *full = fx_package(dir, "v2", 0);
    int V = full->views.n_dirs, L = full->lights.n_dirs;
    int probes[] = {1, 3, COMPS + 2, full->n_chunks};
    btf *all = NULL; /* the whole package's decode, the reference of the comparisons below */
    btf_error aerr = {0};
    cr_assert_eq(btf_package_reconstruct(full, 0, &all, &aerr), BTF_OK, "%s", aerr.msg);
    for (size_t k = 0; k < sizeof probes / sizeof probes[0]; k++) {
        int n = probes[k];
        double e = 0.0;
        for (int v = 0; v < V; v++)
            for (int l = 0; l < L; l++)
                for (int y = 0; y < SIZE; y++)
                    for (int x = 0; x < SIZE; x++) {
                        float a[3], b[3];
                        btf_package_value(full, v, l, x, y, n, a);
                        btf_package_value(full, v, l, x, y, 0, b);
                        for (int c = 0; c < 3; c++)
                            e += (double)(a[c] - b[c]) * (a[c] - b[c]);
                    }
        double rmse = 255.0 * sqrt(e / ((double)V * L * SIZE * SIZE * 3));
        /* float32 texels and weights: agreement to 1e-3 of the 0..255 scale plus 0.1 % */
        cr_assert_float_eq(rmse, manifest_num(dir, "v2", n - 1, "rmse_full"), 1e-3 + 1e-3 * rmse, "prefix %d", n);
        /* btf_package_compare on a levelled package: as btf_compare of the whole decodes */
        btf *rec = NULL;
        btf_metrics m, mv;
        btf_error err = {0};
        cr_assert_eq(btf_package_reconstruct(full, n, &rec, &err), BTF_OK, "%s", err.msg);
        cr_assert_eq(btf_compare(all, rec, NULL, &m, &err), BTF_OK, "%s", err.msg);
        cr_assert_eq(btf_package_compare(full, n, all, &mv, &err), BTF_OK, "%s", err.msg);
        cr_assert_float_eq(mv.rmse, m.rmse, 1e-9 * m.rmse + 1e-12, "prefix %d", n);
        cr_assert_float_eq(mv.lab_thesis, m.lab_thesis, 1e-9 * m.lab_thesis + 1e-12, "prefix %d", n);
        /* with the first prefix in the same pass: the same numbers as alone */
        int ns[2] = {1, n};
        btf_metrics mp[2];
        cr_assert_eq(btf_package_compare_prefixes(full, ns, 2, all, mp, &err), BTF_OK, "%s", err.msg);
        cr_assert_eq(mp[1].lab_thesis, mv.lab_thesis, "prefix %d", n);
        cr_assert_eq(mp[1].rmse, mv.rmse, "prefix %d", n);
        btf_free(rec);
    }
    btf_free(all);
    btf_package_free(full);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* btf_decode with lod: at a measured pair and the centre of a level-l texel, integer
 * lod l gives sum_c T_c^l * Wt_c (computed here from the loaded arrays); lod l + 0.5
 * the mean of levels l and l + 1 sampled bilinearly at that point. */
Test(lod, decode_selects_and_blends_levels)
{
    char dir[256];
    make_packages(dir, sizeof dir, NULL);
    btf_package *p = fx_package(dir, "v2", 0);
    int L = p->lights.n_dirs, vi = 5, li = 7, b = p->blocks->block_of_view[vi];
    float lv[3], vv[3];
    btf_dirset_vector(&p->lights, li, lv);
    btf_dirset_vector(&p->views, vi, vv);
    for (int l = 0; l < LEVELS; l++) {
        int w = SIZE >> l, x = w / 2 + 1, y = w / 3;
        float u = ((float)x + 0.5f) / (float)w, v = ((float)y + 0.5f) / (float)w;
        double want[3] = {0}, half[3] = {0};
        for (int i = 0; i < p->n_chunks; i++) {
            int c = p->chunk[i].component;
            if (p->chunk[i].level != l)
                continue;
            float t = p->tex[i][((size_t)b * w + y) * w + x];
            float t1 = t;
            if (l + 1 < LEVELS) { /* the level-(l+1) value at the same point, bilinear */
                int j = btf_package_chunk_at(p, 0, c, l + 1), w1 = w / 2;
                float fx = u * w1 - 0.5f, fy = v * w1 - 0.5f;
                int x0 = (int)floorf(fx), y0 = (int)floorf(fy);
                float ax = fx - x0, ay = fy - y0, s = 0.0f;
                for (int dy = 0; dy < 2; dy++)
                    for (int dx = 0; dx < 2; dx++) {
                        int xx = x0 + dx < 0 ? 0 : x0 + dx >= w1 ? w1 - 1 : x0 + dx;
                        int yy = y0 + dy < 0 ? 0 : y0 + dy >= w1 ? w1 - 1 : y0 + dy;
                        s += (dx ? ax : 1 - ax) * (dy ? ay : 1 - ay) * p->tex[j][((size_t)b * w1 + yy) * w1 + xx];
                    }
                t1 = s;
            }
            for (int ch = 0; ch < 3; ch++) {
                float wt = p->wt[i][((size_t)vi * L + li) * 3 + ch];
                want[ch] += t * wt;
                half[ch] += 0.5 * (t + t1) * wt;
            }
        }
        btf_decode_options o = {0};
        o.filter = BTF_FILTER_BILINEAR;
        o.lod = (float)l;
        float got[3], gh[3];
        btf_decode(p, u, v, lv, vv, &o, got);
        o.lod = (float)l + 0.5f;
        btf_decode(p, u, v, lv, vv, &o, gh);
        for (int ch = 0; ch < 3; ch++) { /* float32 sums of <= 5 terms: 1e-5 */
            cr_assert_float_eq(got[ch], want[ch], 1e-5, "level %d channel %d", l, ch);
            cr_assert_float_eq(gh[ch], half[ch], 1e-5, "lod %d.5 channel %d", l, ch);
        }
    }
    /* a partial package: component with only its coarsest level loaded is drawn from it at lod 0 */
    btf_package *p1 = fx_package(dir, "v2", 1);
    float a[3], c[3];
    btf_decode_options o = {0};
    btf_decode(p1, 0.3f, 0.6f, lv, vv, &o, a);
    o.lod = (float)(LEVELS - 1);
    btf_decode(p1, 0.3f, 0.6f, lv, vv, &o, c);
    for (int ch = 0; ch < 3; ch++)
        cr_assert_float_eq(a[ch], c[ch], 1e-6);
    btf_package_free(p1);
    btf_package_free(p);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* tests/lod_select_cases.json (shared with tests/e2e/modules.test.mjs), found in the
 * folder above this source file's (tests/codec/; __FILE__ is relative to the
 * repository root, where the tests run) or under $BTF_ROOT. */
static cJSON *lod_cases(void)
{
    char path[700];
    const char *root = getenv("BTF_ROOT");
    if (root)
        snprintf(path, sizeof path, "%s/tests/lod_select_cases.json", root);
    else
        snprintf(path, sizeof path, "%.*s../lod_select_cases.json",
                 (int)(strrchr(__FILE__, '/') ? strrchr(__FILE__, '/') - __FILE__ + 1 : 0), __FILE__);
    FILE *f = fopen(path, "rb");
    cr_assert(f, "%s: cannot open (run from the repository root or set BTF_ROOT)", path);
    static char text[1 << 16];
    size_t n = fread(text, 1, sizeof text - 1, f);
    fclose(f);
    text[n] = 0;
    cJSON *m = cJSON_Parse(text);
    cr_assert(m, "%s: bad JSON", path);
    return m;
}

static double jnum(const cJSON *o, const char *k)
{
    const cJSON *v = cJSON_GetObjectItem(o, k);
    cr_assert(cJSON_IsNumber(v), "case field %s", k);
    return v->valuedouble;
}

/* The selection rule on the hand-made manifest of the shared cases. */
static btf_package *fake_package(const cJSON *pk)
{
    const cJSON *ch = cJSON_GetObjectItem(pk, "chunks");
    int n = cJSON_GetArraySize(ch);
    btf_package *p = calloc(1, sizeof *p);
    p->version = (int)jnum(pk, "version"), p->n_levels = (int)jnum(pk, "levels"), p->n_chunks = n;
    p->width = p->height = (int)jnum(pk, "width");
    p->chunk = calloc((size_t)n, sizeof *p->chunk);
    for (int i = 0; i < n; i++) {
        const cJSON *c = cJSON_GetArrayItem(ch, i);
        p->chunk[i].component = (int)jnum(c, "component"), p->chunk[i].level = (int)jnum(c, "level");
        p->chunk[i].contrib = jnum(c, "contrib"), p->chunk[i].bytes = (long long)jnum(c, "bytes");
        p->n_comp = p->chunk[i].component + 1 > p->n_comp ? p->chunk[i].component + 1 : p->n_comp;
    }
    return p;
}

Test(lod, selection_rule)
{
    cJSON *m = lod_cases();
    btf_package *p = fake_package(cJSON_GetObjectItem(m, "package"));
    const cJSON *cs = cJSON_GetObjectItem(m, "cases");
    cr_assert_gt(cJSON_GetArraySize(cs), 5);
    for (int k = 0; k < cJSON_GetArraySize(cs); k++) {
        const cJSON *c = cJSON_GetArrayItem(cs, k);
        btf_lod_view v = {jnum(c, "tpp"), jnum(c, "threshold")};
        btf_lod_selection s;
        unsigned char need[64];
        cr_assert_leq(p->n_chunks, 64);
        btf_lod_select(p, &v, &s, need);
        char got[65];
        for (int i = 0; i < p->n_chunks; i++)
            got[i] = (char)('0' + need[i]);
        got[p->n_chunks] = 0;
        cr_assert_str_eq(got, cJSON_GetObjectItem(c, "need")->valuestring, "case %d", k);
        if (v.texels_per_pixel > 0)
            cr_assert_eq(s.level, (int)jnum(c, "level"), "case %d", k);
        cr_assert_eq(s.n_components, (int)jnum(c, "components"), "case %d", k);
        cr_assert_eq(s.limit, (int)jnum(c, "limit"), "case %d", k);
        cr_assert_eq(s.bytes, (long long)jnum(c, "bytes"), "case %d", k);
    }
    const cJSON *fp = cJSON_GetObjectItem(m, "footprint");
    for (int k = 0; k < cJSON_GetArraySize(fp); k++) {
        const cJSON *c = cJSON_GetArrayItem(fp, k);
        cr_assert_float_eq(btf_lod_footprint((int)jnum(c, "width"), jnum(c, "repeat"), jnum(c, "pixels")),
                           jnum(c, "tpp"), 1e-12, "footprint case %d", k);
    }
    free(p->chunk);
    free(p);
    cJSON_Delete(m);
}

Test(lod, bad_inputs)
{
    char dir[256], a[600], b[600];
    make_packages(dir, sizeof dir, NULL);
    btf_error err = {0};
    snprintf(a, sizeof a, "%s/v2", dir);
    snprintf(b, sizeof b, "%s/v3", dir);
    cr_assert_neq(btf_lod_build(a, b, NULL, NULL, &err), BTF_OK, "a v2 package is not rebuilt");
    cr_assert(strstr(err.msg, "already"), "%s", err.msg);
    snprintf(a, sizeof a, "%s/v1", dir);
    btf_lod_options o = {0};
    o.levels = 7; /* 32 = 2^5: at most 6 levels */
    cr_assert_neq(btf_lod_build(a, b, &o, NULL, &err), BTF_OK);
    cr_assert_neq(btf_lod_build(a, a, NULL, NULL, &err), BTF_OK, "in place");
    snprintf(a, sizeof a, "%s/none", dir);
    cr_assert_eq(btf_lod_build(a, b, NULL, NULL, &err), BTF_ERR_MISSING, "%s", err.msg);
    /* a level-1 texture of the wrong size, a missing coarse file */
    btf_package *p = fx_package(dir, "v2", 1);
    char f[900], g[900];
    snprintf(f, sizeof f, "%s/v2/%s", dir, p->chunk[0].files[0]);
    snprintf(g, sizeof g, "%s/v2/tex-00.png", dir);
    btf_package_free(p);
    char cmd[4000];
    snprintf(cmd, sizeof cmd, "cp '%s' '%s.bak' && cp '%s' '%s'", f, f, g, f);
    cr_assert_eq(system(cmd), 0);
    snprintf(a, sizeof a, "%s/v2", dir);
    btf_package *q = NULL;
    cr_assert_eq(btf_package_read(a, 1, &q, &err), BTF_ERR_FORMAT, "%s", err.msg);
    cr_assert_null(q);
    remove(f);
    cr_assert_eq(btf_package_read(a, 1, &q, &err), BTF_ERR_MISSING, "%s", err.msg); /* as missing weights */
    cr_assert(strstr(err.msg, "tex-"), "%s", err.msg);
    cr_assert_eq(btf_package_read(a, -1, &q, &err), BTF_ERR_MISSING, "%s", err.msg);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* Compact v2 manifest: ranges once per component (base64 float32) equal to v1's JSON
 * numbers bit for bit; no per-chunk ranges; their text shorter than v1's JSON ranges. Coarse weights: 8 bits (q16 / s_c) in the first
 * chunk, replaced by the exact 16-bit weights when level 0 arrives. */
Test(lod, compact_manifest_and_coarse_weights)
{
    char dir[256], path[700];
    make_packages(dir, sizeof dir, NULL);
    btf_package *p1 = fx_package(dir, "v1", 0), *p = fx_package(dir, "v2", 0), *c = fx_package(dir, "v2", 1);
    int nb = p->blocks->n_blocks, L = p->lights.n_dirs, V = p->views.n_dirs;
    for (int i = 0; i < p->n_chunks; i++) {
        int a = 0;
        while (p1->chunk[a].component != p->chunk[i].component)
            a++;
        cr_assert_eq(memcmp(p->chunk[i].tex_range, p1->chunk[a].tex_range, (size_t)nb * 2 * sizeof(float)), 0);
        cr_assert_eq(memcmp(p->chunk[i].wt_range, p1->chunk[a].wt_range, (size_t)nb * 2 * sizeof(float)), 0);
        cr_assert_eq(memcmp(p->wt[i], p1->wt[a], (size_t)V * L * 3 * sizeof(float)), 0, "chunk %d: 16-bit weights", i);
    }
    /* the ranges' text: v2's base64 once per component against v1's JSON numbers per chunk */
    size_t rg[2] = {0, 0};
    for (int k = 0; k < 2; k++) {
        snprintf(path, sizeof path, "%s/%s/manifest.json", dir, k ? "v2" : "v1");
        size_t n;
        char *txt = fx_read(path, &n);
        cJSON *m = cJSON_ParseWithLength(txt, n), *x;
        cr_assert_not_null(m);
        cJSON *ranges = cJSON_GetObjectItem(m, "ranges"), *chunks = cJSON_GetObjectItem(m, "chunks");
        cr_assert_eq(!!ranges, k, "%s: ranges once per component", k ? "v2" : "v1");
        cJSON_ArrayForEach(x, ranges)
            rg[k] += strlen(cJSON_GetStringValue(x));
        cJSON_ArrayForEach(x, chunks) {
            cr_assert_eq(!!cJSON_GetObjectItem(x, "tex_range"), !k, "%s: ranges per chunk", k ? "v2" : "v1");
            for (int j = 0; j < 2 && !k; j++) {
                char *t = cJSON_PrintUnformatted(cJSON_GetObjectItem(x, j ? "wt_range" : "tex_range"));
                rg[k] += strlen(t);
                free(t);
            }
        }
        cJSON_Delete(m);
        free(txt);
    }
    cr_assert(rg[1] > 0 && rg[1] < rg[0], "v2 ranges %zu B, v1 %zu B", rg[1], rg[0]);
    /* v1's numbers are the shortest decimals of their floats (at most 9 significant
     * digits: "[a,b]," and about 12 characters a number, not a double's 17 digits) */
    size_t numbers = (size_t)p1->n_chunks * 2 * (size_t)nb * 2;
    cr_expect_leq(rg[0], numbers * 14, "v1 ranges %zu B for %zu numbers", rg[0], numbers);
    /* chunk 0 alone: 8-bit weights within half an 8-bit step (257 16-bit steps) of the 16-bit ones */
    int a = 0, coarse = 0;
    while (p1->chunk[a].component != c->chunk[0].component)
        a++;
    for (size_t k = 0; k < (size_t)V * L * 3; k++) {
        float st = p1->chunk[a].wt_range[2 * p->blocks->block_of_view[k / (3 * (size_t)L)] + 1];
        float d = fabsf(c->wt[0][k] - p1->wt[a][k]);
        cr_assert_leq(d, 0.5f * (float)c->chunk[0].wt8_step * st * 1.001f + 1e-7f, "weight %zu", k);
        coarse += d > 0.5f * st;
    }
    cr_assert_gt(coarse, 0, "the first chunk's weights are really 8-bit");
    /* the step multiplier is a whole number and reaches the 16-bit codes in 255 steps
     * (these weights span the 16 bits: at least 257) */
    double m = c->chunk[0].wt8_step;
    cr_assert(m >= 257.0 && m == floor(m), "weights8_step %g", m);
    btf_package_free(c);
    /* a negative "weights8_step" and a damaged "ranges" entry are format errors naming them */
    snprintf(path, sizeof path, "%s/v2/manifest.json", dir);
    char cmd[4000], pkg[700];
    snprintf(pkg, sizeof pkg, "%s/v2", dir);
    snprintf(cmd, sizeof cmd, "cp '%s' '%s.bak' && sed -i 's/\"weights8_step\":\\[[0-9]*/\"weights8_step\":[-3/' '%s'",
             path, path, path);
    cr_assert_eq(system(cmd), 0);
    btf_package *q = NULL;
    btf_error err = {0};
    cr_assert_eq(btf_package_read(pkg, 1, &q, &err), BTF_ERR_FORMAT, "%s", err.msg);
    cr_assert(strstr(err.msg, "weights8_step"), "%s", err.msg);
    snprintf(cmd, sizeof cmd, "mv '%s.bak' '%s'", path, path);
    cr_assert_eq(system(cmd), 0);
    snprintf(cmd, sizeof cmd, "sed -i 's/\"ranges\":\\[\"A/\"ranges\":[\"!/; s/\"ranges\":\\[\"[^\"]/\"ranges\":[\"!/' '%s'",
             path);
    cr_assert_eq(system(cmd), 0);
    cr_assert_eq(btf_package_read(pkg, 1, &q, &err), BTF_ERR_FORMAT, "%s", err.msg);
    cr_assert(strstr(err.msg, "ranges"), "%s", err.msg);
    cr_assert_null(q);
    btf_package_free(p1);
    btf_package_free(p);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* btf_lod_compress, the library call `btf compress --levels` makes: the same
 * package as btf_package_compress then btf_lod_build, and without levels the
 * same as btf_package_compress; nothing but OUT is left beside it. */
Test(lod, lod_compress_is_compress_then_build)
{
    char dir[512], x[600], a[700], b[600];
    btf_lod_stats st = {0};
    make_packages(dir, sizeof dir, &st); /* dir/v1, and dir/v2 from it by btf_lod_build */
    snprintf(x, sizeof x, "%s/x", dir); /* the same names in another folder */
    cr_assert_eq(mkdir(x, 0700), 0);
    btf_dirset d = fx_dirs11();
    btf *src = fx_gen(BTF_GEN_KNIT, SIZE, &d, BTF_U8);
    btf_error err = {0};
    btf_pca_options po = {0};
    po.k = 3, po.components = COMPS;
    btf_lod_options lo = {0};
    lo.levels = LEVELS;
    btf_compress_stats cs = {0};
    snprintf(a, sizeof a, "%s/v2", x);
    snprintf(b, sizeof b, "%s/v2", dir);
    btf_package_options ko = {0};
    ko.name = "v1"; /* btf_lod_build keeps its input's name: dir/v2 is named v1 */
    cr_assert_eq(btf_lod_compress(src, &po, &ko, &lo, a, &cs, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(cs.bytes, st.bytes);
    cr_assert_eq(cs.n_chunks, st.n_chunks);
    cr_assert(fx_same_file(a, b, "manifest.json"), "btf_lod_compress wrote another manifest than compress + build");
    btf_package *p = fx_package(x, "v2", 0);
    cr_assert_eq(p->n_levels, LEVELS);
    for (int i = 0; i < p->n_chunks; i++)
        for (int f = 0; f < p->chunk[i].n_files; f++)
            cr_expect(fx_same_file(a, b, p->chunk[i].files[f]), "%s differs", p->chunk[i].files[f]);
    btf_package_free(p);
    /* no levels: version 1, as btf_package_compress writes it */
    snprintf(a, sizeof a, "%s/v1", x);
    snprintf(b, sizeof b, "%s/v1", dir);
    cr_assert_eq(btf_lod_compress(src, &po, NULL, NULL, a, NULL, &err), BTF_OK, "%s", err.msg);
    cr_assert(fx_same_file(a, b, "manifest.json"));
    cr_assert_eq(fx_count_files(x), 2, "only v1 and v2 in %s", x);
    btf_free(src);
    cr_assert_eq(fx_rmtree(dir), 0);
}
