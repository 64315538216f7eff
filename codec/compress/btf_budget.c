/* btf_budget.c - compression to a byte budget or a CIELab target: one compression
 * per candidate k, every prefix measured from its manifest, the best cut and kept. */
#include "btf_budget.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "btf_compress.h"
#include "btf_fs.h"
#include "btf_manifest.h"
#include "btf_rd.h"
#include "btf_common.h"

#define BTF__BUDGET_K_START 9 /* the default walk's first k (btf__budget_ks) */
/* Under an error target the walk grows a losing larger k only when its error is
 * within this factor of the target: 1.5x the components lowered the error by 4.5-8.6%
 * on the generated stone (k 27: 1.834 -> 1.676, the target 1.6771; k 81: 2.181 ->
 * 2.082), and the thesis wool at k 27 missed by 2.4x. */
#define BTF__BUDGET_GROW_REACH 1.15
/* Under a byte budget the walk grows a losing larger k only when its error times this
 * factor is below the best's: one step of 1.5x the components took a candidate's error
 * to 0.74-1.07 times it in the searches measured (k 5 to k 37; 16x16 to 256x256), so
 * one further behind cannot catch up. The k 27 of the generated stone 3623 at 64x64
 * (CIELab 1.627 against k 9's 1.098), of the thesis corduroy at 64x64 (0.813 against
 * 0.506) and at 256x256 (1.219 against 0.725) were grown and lost. */
#define BTF__BUDGET_GROW_GAIN 0.7
/* What one growth step (1.5x the components) does to a candidate under an error target
 * before its own step is measured: its error times 0.88 and its bytes times 1.45
 * (typical of the steps measured: error 0.74-1.07, bytes 1.41-1.45 times). */
#define BTF__BUDGET_GROW_LAB 0.88
#define BTF__BUDGET_GROW_BYTES 1.45
/* A grown candidate (more components, btf__budget_grown) replaces the best only when
 * its error (bytes, under an error target) is below this factor of the best's: it is
 * measured near the steps of the one it grew from, and its edge may be that
 * measure's noise. The tiles 3621 at 64x64 under 486,281 bytes: k 3 with 24
 * components estimated at CIELab 1.2085 against 1.2095 with 16 (0.08% better) came
 * out at 1.2179 as written, where the 16 fitted again came to 1.1871. */
#define BTF__BUDGET_GROWN_EDGE 0.99
/* The centred retry is tried on the walk's best and also on the runner-up of another
 * k when that came within this factor of the best (bytes under an error target, error
 * under a byte budget): centring changes a candidate's bytes by 5-10%, more than the
 * gap. The tiles 3621 at 64x64 under CIELab 2.2555 with lossy weights: k 81 took
 * 92,145 bytes and k 41 93,119 (1.06% more); k 81 centred 100,616, k 41 centred
 * 87,284. */
#define BTF__BUDGET_RUNNER_UP 1.03

/* The written winner is fitted again, to the budget plus what it left, when it
 * comes out under the budget by more than 1/BTF__BUDGET_SLACK of it with every chunk
 * its allocation kept, where that allocation expected to fill the budget to within
 * the same share (btf__budget_refit; not one that kept its finest steps below it): the
 * tiles 3621 at 64x64, k 3, under 486,281 bytes came out at 449,547 and CIELab
 * 1.2117, fitted again at 485,045 and 1.1871. Since the manifest estimate counts
 * version 3's header ranges, the same write comes out 1.2% under (480,373 B, 1.1490),
 * and fitted again at 1% takes 485,045 B at 1.1460 (doc/performance.md section 3). */
#define BTF__BUDGET_SLACK 100
/* Under an error target, the bisection over byte budgets of btf__budget_fit_error:
 * at most this many trials, from half the equal-noise winner's bytes up to them
 * (the last step about 3% of them) */
#define BTF__BUDGET_FIT_TRIALS 5
/* ... and the bisection goes on past three misses while the last missed the target by
 * at most this factor: the thesis corduroy at 64x64 (k 3 centred, its 8 components,
 * CIELab 0.4073) missed at 280, 327 and 350 KB, the last at 0.4146, 1.8% over, where
 * the equal-noise steps took 385 KB (doc/performance.md section 3) */
#define BTF__BUDGET_FIT_NEAR 1.03

/* The candidate k values, within 1..views: the budget's in its order, else the
 * default walk's: 9 (or the largest of the others below it), then the larger ones
 * ascending (27, 81, ... each 3x the last below the view count; then half the view
 * count, rounded up, where the last of those leaves more than two blocks; then the
 * view count: one basis for every view), then the smaller ones descending (5, the
 * step between 9 and 3, then 3, 1). The two-block k: on 81 views k 41 took
 * 0.95-0.97x the bytes of k 27 on generated tiles at 64x64 under the thesis format's
 * error (k 81: 1.17x), 1.3x on a stone (doc/performance.md section 4, "Two blocks");
 * k 5: at the thesis format's bytes 0.87x the error of k 3 on the tiles 3621 and
 * 0.98x on the knit 3622, grown (section 3, "k 5"). */
static int btf__budget_ks(const btf_budget *b, int views, int *ks)
{
    int n = 0;
    if (b->n_k > 0) {
        for (int i = 0; i < b->n_k && i < BTF_BUDGET_MAX_K; i++)
            if (b->k[i] >= 1 && b->k[i] <= views)
                ks[n++] = b->k[i];
        return n;
    }
    int up[BTF_BUDGET_MAX_K], nu = 0; /* 1, 3, 9, ... below views, maybe two blocks, then views */
    for (long k = 1; k < views && nu < BTF_BUDGET_MAX_K - 1; k *= 3)
        up[nu++] = (int)k;
    int two = (views + 1) / 2; /* two blocks, where the last power leaves more */
    if (nu > 0 && nu < BTF_BUDGET_MAX_K - 1 && two > up[nu - 1] && (views + up[nu - 1] - 1) / up[nu - 1] > 2)
        up[nu++] = two;
    up[nu++] = views;
    int s = 0;
    while (s + 1 < nu && up[s + 1] <= BTF__BUDGET_K_START)
        s++;
    for (int i = s; i < nu; i++)
        ks[n++] = up[i];
    if (s > 0 && up[s] == 3 * up[s - 1] && n < BTF_BUDGET_MAX_K - s) /* 5 between 9 and 3 */
        ks[n++] = (int)lround(sqrt((double)up[s] * up[s - 1]));
    for (int i = s - 1; i >= 0; i--)
        ks[n++] = up[i];
    return n;
}

/* 1 when the default ks are walked (the caller listed no ks and asked for no full
 * search): from the first, larger ones while each beats the best before it, and
 * smaller ones (while each beats the best) only when no larger one won
 * (btf__budget_walk). The bytes a k needs for an error (or the error in a budget)
 * fall and then rise as k grows: blocks of more views share their textures, but need
 * more components. On generated tiles, knit and stone at 64x64 under the thesis
 * format's error k 27 or 81 won (0.67-0.84x the bytes of k 9), on the thesis's wool
 * and corduroy k 1 and 3 (doc/performance.md section 4, "The search's k"). */
static int btf__budget_prunes(const btf_budget *b)
{
    return b->n_k <= 0 && !b->full_search;
}

/* Bytes of the package made of the first n chunks of p: its manifest and files. */
static long long btf__prefix_bytes(btf_package *p, int n)
{
    int all = p->n_chunks;
    p->n_chunks = n;
    char *text = btf_manifest_print(p, NULL);
    p->n_chunks = all;
    long long bytes = text ? (long long)strlen(text) : 0;
    free(text);
    for (int i = 0; i < n; i++)
        bytes += p->chunk[i].bytes;
    return bytes;
}

/* The best prefix of p under b (see btf_budget); n_chunks 0 when none fits. */
static btf_budget_choice btf__best_prefix(btf_package *p, const btf_budget *b, int *met)
{
    btf_budget_choice c = {.k = p->k, .bytes = btf__prefix_bytes(p, 1)}, low = c; /* none: what one chunk needs */
    *met = 0;
    for (int n = 1; n <= p->n_chunks; n++) {
        btf_budget_choice t = {.k = p->k, .n_chunks = n, .bytes = btf__prefix_bytes(p, n), .lab = p->chunk[n - 1].lab,
                               .rmse = p->chunk[n - 1].rmse};
        if (low.n_chunks == 0 || t.lab < low.lab)
            low = t;
        if (b->max_bytes > 0 && t.bytes <= b->max_bytes && (c.n_chunks == 0 || t.lab < c.lab))
            c = t, *met = 1;
        if (b->max_error > 0 && t.lab <= b->max_error && c.n_chunks == 0)
            c = t, *met = 1;
    }
    return b->max_error > 0 && !*met ? low : c; /* an unreachable target: the lowest error, reported as unmet */
}

/* The "budget" record of the manifest: what was asked, chosen and measured. */
static char *btf__budget_json(const btf_budget *b, const btf_budget_result *res)
{
    cJSON *o = cJSON_CreateObject(), *cands = NULL;
    if (b->max_bytes > 0)
        cJSON_AddNumberToObject(o, "max_bytes", (double)b->max_bytes);
    else
        cJSON_AddNumberToObject(o, "max_error", b->max_error);
    cJSON_AddBoolToObject(o, "met", res->met);
    cJSON_AddNumberToObject(o, "k", res->k);
    cJSON_AddNumberToObject(o, "components", res->components);
    if (res->rd_fit)
        cJSON_AddStringToObject(o, "rd_steps", "fitted");
    if (res->tex_noise > 0.0f) /* an error target the default steps did not reach: finer ones */
        cJSON_AddNumberToObject(o, "tex_noise", res->tex_noise);
    if (res->center == BTF_CENTER_ROW)
        cJSON_AddStringToObject(o, "center", "row");
    cJSON_AddNumberToObject(o, "chunks", res->n_chunks);
    cJSON_AddNumberToObject(o, "bytes", (double)res->bytes);
    cJSON_AddNumberToObject(o, "lab", res->lab);
    if (res->screen_width > 0) {
        int wh[2] = {res->screen_width, res->screen_height};
        cJSON_AddItemToObject(o, "screen", cJSON_CreateIntArray(wh, 2));
    }
    cands = cJSON_AddArrayToObject(o, "candidates");
    for (int i = 0; cands && i < res->n_candidates; i++) {
        const btf_budget_choice *c = &res->candidate[i];
        cJSON *e = cJSON_CreateObject();
        cJSON_AddNumberToObject(e, "k", c->k);
        cJSON_AddNumberToObject(e, "components", c->components);
        if (c->rd_fit)
            cJSON_AddStringToObject(e, "rd_steps", "fitted");
        if (c->center == BTF_CENTER_ROW)
            cJSON_AddStringToObject(e, "center", "row");
        cJSON_AddNumberToObject(e, "chunks", c->n_chunks);
        cJSON_AddNumberToObject(e, "bytes", (double)c->bytes);
        cJSON_AddNumberToObject(e, "lab", c->lab);
        cJSON_AddItemToArray(cands, e);
    }
    char *s = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    return s;
}

/* Cuts the package in dir to its first n chunks and records the budget. */
static btf_result btf__budget_cut(const char *dir, int n, char *budget_json, btf_error *err)
{
    btf_package p;
    btf_result r = btf_manifest_load(dir, &p, err);
    char path[BTF_FS_PATH_MAX + 80];
    for (int i = n; r == BTF_OK && i < p.n_chunks; i++)
        for (int f = 0; f < p.chunk[i].n_files; f++) {
            snprintf(path, sizeof path, "%s/%s", dir, p.chunk[i].files[f]);
            unlink(path); /* a file of a dropped chunk, named by our own manifest */
        }
    char *text = NULL;
    if (r == BTF_OK) {
        int all = p.n_chunks;
        char *old = p.budget; /* the record of an earlier round, if any: replaced */
        p.n_chunks = n, p.budget = budget_json;
        text = btf_manifest_print(&p, err);
        p.budget = old, p.n_chunks = all; /* btf_manifest_clear frees every chunk's ranges */
        r = text ? BTF_OK : BTF_ERR_NOMEM;
    }
    snprintf(path, sizeof path, "%s/manifest.json", dir);
    if (r == BTF_OK)
        r = btf_fs_write_atomic(path, text, strlen(text), err);
    free(text);
    btf_manifest_clear(&p);
    return r;
}

/* Bytes of the package in dir as written: its manifest and the files it lists. */
static long long btf__package_bytes(const char *dir)
{
    btf_package p;
    char path[BTF_FS_PATH_MAX + 80];
    snprintf(path, sizeof path, "%s/manifest.json", dir);
    long long n = btf_fs_size(path);
    if (btf_manifest_load(dir, &p, NULL) != BTF_OK)
        return -1;
    for (int i = 0; i < p.n_chunks; i++)
        for (int f = 0; f < p.chunk[i].n_files; f++) {
            snprintf(path, sizeof path, "%s/%s", dir, p.chunk[i].files[f]);
            n += btf_fs_size(path);
        }
    btf_manifest_clear(&p);
    return n;
}

/* Cuts the chosen package and records the budget; the record itself takes bytes, so
 * under a byte budget the cut drops chunks until the package as written fits. */
static btf_result btf__budget_finish(const char *dir, const btf_budget *b, btf_budget_result *rs, btf_error *err)
{
    btf_result r = BTF_OK;
    for (int round = 0; round < 4 * BTF_PACKAGE_MAX_CHUNKS; round++) { /* ends: chunks only decrease */
        char *json = btf__budget_json(b, rs);
        r = json ? btf__budget_cut(dir, rs->n_chunks, json, err) : btf_fail(err, BTF_ERR_NOMEM, "budget: out of memory");
        free(json);
        long long real = r == BTF_OK ? btf__package_bytes(dir) : -1;
        if (r != BTF_OK || real < 0 || b->max_bytes <= 0 || real <= b->max_bytes || rs->n_chunks <= 1) {
            if (r != BTF_OK || real < 0 || real == rs->bytes || round > 2 * BTF_PACKAGE_MAX_CHUNKS)
                return r;
            rs->bytes = real; /* once more, so the record states the bytes as written */
            continue;
        }
        btf_package p; /* one chunk fewer: its error from the manifest */
        if ((r = btf_manifest_load(dir, &p, err)) != BTF_OK)
            return r;
        rs->n_chunks--;
        rs->lab = p.chunk[rs->n_chunks - 1].lab, rs->rmse = p.chunk[rs->n_chunks - 1].rmse;
        btf_manifest_clear(&p);
    }
    return r;
}

/* The most components, up to n, that blocks of k views of src hold. */
static int btf__fit_components(const btf *src, btf_pca_options po, int k, int n)
{
    po.k = k, po.components = n;
    while (po.components > 1 && btf_pca_check(src, &po, NULL) != BTF_OK)
        po.components--; /* small blocks hold fewer components */
    return po.components;
}

/* Bytes of chunk i's texture files (tex-*) of p, as written in dir; 0 when none. */
static long long btf__chunk_tex_bytes(const btf_package *p, const char *dir, int i)
{
    char path[BTF_FS_PATH_MAX + 80];
    long long sum = 0;
    for (int f = 0; f < p->chunk[i].n_files; f++)
        if (!strncmp(p->chunk[i].files[f], "tex-", 4)) {
            snprintf(path, sizeof path, "%s/%s", dir, p->chunk[i].files[f]);
            long long n = btf_fs_size(path);
            sum += n > 0 ? n : 0;
        }
    return sum;
}

/* Counts the texture files of every chunk of p, written in dir, scale times over (a
 * version-1 package of the search's window standing for the whole material; a
 * version-3 estimate scales its rates itself: btf_package_channel.tex_rate_scale). */
static void btf__budget_scale_textures(btf_package *p, const char *dir, double scale)
{
    for (int i = 0; i < p->n_chunks; i++) {
        long long n = btf__chunk_tex_bytes(p, dir, i);
        p->chunk[i].bytes += n > 0 ? llround((double)n * (scale - 1.0)) : 0;
    }
}

/* Compresses candidate k with up to n components into dir, or with estimate (rd
 * only) measures it without writing anything (btf_package_channel.estimate), and
 * reads off its best prefix; *all_kept = 1 when that prefix is every chunk and the
 * count stopped it, not the source's rounding; *rank: the components its model holds
 * (btf_pca_model_rank, with rd; else n). */
static btf_result btf__budget_try(const btf *src, btf_pca_options po, const btf_package_options *o,
                                  btf_package_channel ch, int k, int n,
                                  const btf_budget *b, const char *dir, int estimate, btf_budget_choice *c, int *met,
                                  int *all_kept, int *rank, btf_error *err)
{
    po.k = k;
    po.components = btf__fit_components(src, po, k, n);
    char *text = NULL;
    ch.estimate = estimate ? &text : NULL;
    btf_fs_rmtree(dir, NULL);
    btf_result r = btf_package_compress_with(src, &po, o, &ch, dir, NULL, err);
    if (r != BTF_OK)
        return r;
    btf_package p;
    memset(&p, 0, sizeof p);
    r = estimate ? btf_manifest_parse(text, dir, &p, err) : btf_manifest_load(dir, &p, err);
    if (r == BTF_OK && !estimate && ch.tex_rate_scale > 1.0)
        btf__budget_scale_textures(&p, dir, ch.tex_rate_scale);
    if (r == BTF_OK) {
        *c = btf__best_prefix(&p, b, met);
        c->components = po.components;
        *rank = ch.rd_model && *ch.rd_model ? btf_pca_model_rank(*ch.rd_model) : po.components;
        *all_kept = c->n_chunks > 0 && c->n_chunks == p.n_chunks && *rank >= po.components;
    }
    btf_manifest_clear(&p);
    free(text);
    return r;
}

/* The candidate list of a search: settings in, measurements out; owned by
 * btf_budget_compress for one call. */
typedef struct btf__search {
    const btf *src;
    /* what the candidates are measured on, src or its centre window
     * (btf__budget_screen; owned here when it is not src), and that window's
     * texture bytes factor */
    const btf *screen;
    double screen_scale;
    btf_pca_options pca;
    btf_package_options po;
    btf_package_channel hook; /* the caller's write_hook and hook_ctx, passed to every write */
    const btf_budget *b;
    const char *out;
    char dir[BTF_BUDGET_MAX_CANDIDATES][BTF_FS_PATH_MAX];
    int all_kept[BTF_BUDGET_MAX_CANDIDATES]; /* 1: the candidate's best prefix is all its chunks */
    int rank[BTF_BUDGET_MAX_CANDIDATES];     /* the components its model holds (btf__budget_try) */
    int clipped; /* 1: a byte budget, and the PCA fits the screened source's clipped samples (btf__budget_shrink) */
    btf_budget_result rs;
    int best, best_met;
    /* with rd: [0] the best candidate's PCA model, measured steps and chosen steps
     * (the winner is written from the first two when there is no window, with its
     * ladder measured near the third when there is one), [1] the last other
     * candidate's */
    btf_pca_model *model[2];
    btf_rd_ladder ladder[2];
    btf_rd_result rd[2];
    long long fit_bytes; /* with rd: the bytes steps are fitted to, 0 = the budget's (btf__budget_refit) */
    int final_kept;      /* with rd: components the written winner's allocation kept within them */
    long long final_est; /* with rd: the bytes that allocation expected its files to take */
    long long *final_tex; /* with rd: its estimate of each component's atlas (malloc'd, n_final) */
    int n_final;
    double *tex_fix;     /* NULL, or per component the atlas written over its estimate (the refit) */
} btf__search;

/* 1 when candidates a and b have the same PCA model: k, components, centring. */
static int btf__budget_same_model(const btf_budget_choice *a, const btf_budget_choice *b)
{
    return a->k == b->k && a->components == b->components && a->center == b->center;
}

/* The model and ladder slot of candidate i: the best's when it has the best's model. */
static int btf__budget_model_slot(const btf__search *s, int i)
{
    return s->best >= 0 && btf__budget_same_model(&s->rs.candidate[s->best], &s->rs.candidate[i]) ? 0 : 1;
}

/* What candidate i's ladder is measured near (btf_package_channel.rd_near), or NULL
 * for every step: the best's choice on the window when the best is written from the
 * whole material, the one it grew from for a grown candidate (its first components),
 * the best's for its centred retry. Measured on tiles, stone and knit at 128x128: the
 * same steps as with every step measured, at half the ladder's time
 * (doc/package-format.md section 11.4); the centred retry near the best's choice
 * gave the same packages on tiles, knit and stone at 64x64 under --max-error
 * (bytes within 1) for 4-10% less CPU. Not on a window, where the winner is written
 * near its choice again: near a choice made near another model's, the thesis
 * corduroy at 256x256 (k 3, centred, 8 components past the rounding cut) was written
 * at 7 of them in 4.0 of its 4.49 MB budget, CIELab 0.495 against 0.156 (its
 * lossless steps measured only at the finest rungs, where the window chose lossy). */
static const btf_rd_result *btf__budget_near(const btf__search *s, int i, int final)
{
    const btf_budget_choice *c = &s->rs.candidate[i], *b = s->best >= 0 ? &s->rs.candidate[s->best] : NULL;
    if (!s->po.rd || !b || s->rd[0].n_comp < 1)
        return NULL;
    if (final)
        return s->screen != s->src ? &s->rd[0] : NULL;
    if (b->k == c->k && b->center != c->center && b->components == c->components)
        return s->screen == s->src ? &s->rd[0] : NULL; /* the centred retry of the best, not on a window */
    return b->k == c->k && b->center == c->center && b->components < c->components ? &s->rd[0] : NULL;
}

/* Keeps what the written winner's allocation rd kept and estimated, for the refit;
 * frees rd. */
static void btf__budget_keep_final(btf__search *s, btf_rd_result *rd)
{
    s->final_kept = rd->n_kept, s->final_est = rd->bytes_rd;
    free(s->final_tex);
    s->final_tex = rd->tex_bytes, s->n_final = rd->tex_bytes ? rd->n_comp : 0;
    rd->tex_bytes = NULL;
    btf_rd_result_free(rd);
}

/* Candidate i measured with its settings on the search's window (final: compressed
 * from the whole material and written); into *got. With rd a measured candidate is
 * only estimated, without it written on the window. */
static btf_result btf__budget_run(btf__search *s, int i, int final, btf_budget_choice *got, int *met,
                                  btf_error *err)
{
    int estimate = s->po.rd && !final;
    const btf_budget_choice *c = &s->rs.candidate[i];
    snprintf(s->dir[i], sizeof s->dir[i], "%s.tmp-%ld-k%d-c%d%s%s", s->out, (long)getpid(), c->k, c->components,
             c->rd_fit ? "f" : "", c->center == BTF_CENTER_ROW ? "r" : "");
    btf_package_options po = s->po;
    btf_package_channel ch = {0};
    ch.write_hook = s->hook.write_hook, ch.hook_ctx = s->hook.hook_ctx;
    int slot = btf__budget_model_slot(s, i);
    ch.rd_max_bytes = !c->rd_fit ? 0 : s->fit_bytes > 0 ? s->fit_bytes : s->b->max_bytes;
    ch.rd_ladder = po.rd ? &s->ladder[slot] : NULL;
    ch.rd_model = po.rd ? &s->model[slot] : NULL;
    btf_rd_result rd = {0}; /* what this allocation chooses */
    ch.rd_out = po.rd ? &rd : NULL;
    ch.rd_near = btf__budget_near(s, i, final);
    ch.rd_tex_fix = final ? s->tex_fix : NULL;
    btf_pca_options pca = s->pca;
    pca.center = c->center;
    const btf *src = final ? s->src : s->screen;
    if (src != s->src) { /* the window's textures stand for the material's */
        ch.tex_rate_scale = s->screen_scale;
        int lab = (int)((po.lab_max_texels > 0 ? po.lab_max_texels : 256) / s->screen_scale);
        po.lab_max_texels = lab > 16 ? lab : 16;
    }
    *got = (btf_budget_choice){0};
    btf_result r = btf__budget_try(src, pca, &po, ch, c->k, c->components, s->b, s->dir[i], estimate, got, met,
                                   &s->all_kept[i], &s->rank[i], err);
    got->rd_fit = c->rd_fit, got->center = c->center; /* the settings it was made with */
    if (!final) /* kept with the model: the winner's whole-material ladder is measured near it */
        btf_rd_result_free(&s->rd[slot]), s->rd[slot] = rd;
    else
        btf__budget_keep_final(s, &rd);
    return r;
}

/* Measures candidate i (k, components, rd_fit and center already in
 * rs.candidate[i]; on the window; with rd estimated, nothing written) and keeps it
 * as the best if it keeps at least min_chunks chunks and its error (bytes, for an
 * error target) is below edge x the best's. */
static btf_result btf__budget_eval(btf__search *s, int i, int min_chunks, double edge, btf_error *err)
{
    btf_budget_choice got;
    int met = 0;
    int slot = btf__budget_model_slot(s, i);
    btf_result r = btf__budget_run(s, i, 0, &got, &met, err);
    btf_budget_choice *c = &s->rs.candidate[i];
    *c = got;
    s->rs.n_candidates = i + 1;
    const btf_budget_choice *bc = s->best >= 0 ? &s->rs.candidate[s->best] : NULL;
    int better = c->n_chunks > 0 && c->n_chunks >= min_chunks &&
                 (!bc || met > s->best_met ||
                  (met == s->best_met && (s->b->max_bytes > 0 || !met ? c->lab < edge * bc->lab
                                                                       : c->bytes < edge * bc->bytes)));
    if (r == BTF_OK && better && slot == 1) { /* its model and steps are the best's now */
        btf_pca_model *m = s->model[0];
        btf_rd_ladder l = s->ladder[0];
        s->model[0] = s->model[1], s->model[1] = m;
        s->ladder[0] = s->ladder[1], s->ladder[1] = l;
        btf_rd_result rd = s->rd[0];
        s->rd[0] = s->rd[1], s->rd[1] = rd;
    }
    if (r == BTF_OK && better)
        s->best = i, s->best_met = met;
    return r;
}

/* Per component of the written winner (package p in dir), its atlas as written over
 * the allocation's estimate of it (s->final_tex); a component without a written
 * chunk gets the ratio of all written atlases over their estimates. malloc'd
 * (n_final), or NULL when nothing was measured or without memory. */
static double *btf__budget_tex_fix(const btf__search *s, const btf_package *p, const char *dir)
{
    double *fix = s->n_final > 0 ? calloc((size_t)s->n_final, sizeof(double)) : NULL;
    double got = 0.0, est = 0.0;
    for (int q = 0; fix && q < p->n_chunks; q++) {
        int j = p->chunk[q].component;
        long long n = j >= 0 && j < s->n_final ? btf__chunk_tex_bytes(p, dir, q) : 0;
        if (n > 0 && s->final_tex[j] > 0)
            fix[j] = (double)n / (double)s->final_tex[j], got += (double)n, est += (double)s->final_tex[j];
    }
    if (fix && !(est > 0.0))
        free(fix), fix = NULL;
    for (int j = 0; fix && j < s->n_final; j++)
        fix[j] = fix[j] > 0.0 ? fix[j] : got / est;
    return fix;
}

/* The written winner's steps fitted again when the chunks its allocation kept, as
 * written, and the budget record came out under the budget by more than
 * 1/BTF__BUDGET_SLACK of it (fitted to the budget plus what they left), or over the
 * budget with the cut dropping some of them (the chunk order is by error drop per
 * byte, so the kept components are taken as the first chunks): the allocation's
 * estimates fill the budget to within a few hundred bytes, but an atlas estimated
 * from a sample of its tile rows can come out several percent larger, and the cut
 * then loses a whole chunk. Fitted again to the budget less the record and 0.2%,
 * each component's texture rates scaled by its atlas as written over its estimate
 * (btf_rd_params.tex_rate_fix). The better of the two writes is kept in the
 * candidate's directory. */
static btf_result btf__budget_refit(btf__search *s, btf_budget_choice *got, int *met, btf_error *err)
{
    int i = s->best;
    btf_package p;
    if (!s->po.rd || !s->rs.candidate[i].rd_fit || s->b->max_bytes <= 0 ||
        btf_manifest_load(s->dir[i], &p, NULL) != BTF_OK)
        return BTF_OK;
    int n = s->final_kept < p.n_chunks ? s->final_kept : p.n_chunks;
    long long kept_bytes = btf__prefix_bytes(&p, n); /* the chunks the allocation fitted, as written */
    char *json = btf__budget_json(s->b, &s->rs);
    long long record = json ? (long long)strlen(json) + 64 : 4096;
    free(json);
    long long over = kept_bytes + record - s->b->max_bytes;
    int cut = got->n_chunks < s->final_kept && over > 0; /* the bytes cut chunks it kept */
    long long share = s->b->max_bytes / BTF__BUDGET_SLACK; /* left unused, and expected used */
    int slack = got->n_chunks >= s->final_kept && -over > share && s->final_est >= s->b->max_bytes - share;
    long long fit = s->b->max_bytes - record - s->b->max_bytes / 500;
    s->tex_fix = cut ? btf__budget_tex_fix(s, &p, s->dir[i]) : NULL;
    if (!s->tex_fix) /* no measured atlas, or under the budget: the budget less the overshoot */
        fit = s->b->max_bytes - over - s->b->max_bytes / 500;
    btf_manifest_clear(&p);
    char aside[BTF_FS_PATH_MAX + 8];
    snprintf(aside, sizeof aside, "%s.first", s->dir[i]);
    if ((!cut && !slack) || fit <= 0 || rename(s->dir[i], aside) != 0) {
        free(s->tex_fix), s->tex_fix = NULL;
        return BTF_OK; /* the error curve cut the chunks, not the bytes; or the first write stands */
    }
    btf_budget_choice again;
    int met2 = 0, kept = s->all_kept[i], rank = s->rank[i];
    s->fit_bytes = fit;
    btf_result r = btf__budget_run(s, i, 1, &again, &met2, err);
    s->fit_bytes = 0;
    s->rs.refits = 1, s->rs.first = *got;
    free(s->tex_fix), s->tex_fix = NULL;
    if (r == BTF_OK && again.n_chunks > 0 && (met2 > *met || (met2 == *met && again.lab < got->lab))) {
        *got = again, *met = met2;
        btf_fs_rmtree(aside, NULL);
        return BTF_OK;
    }
    btf_fs_rmtree(s->dir[i], NULL); /* the refit lost (or failed): the first write stands */
    s->all_kept[i] = kept, s->rank[i] = rank;
    if (rename(aside, s->dir[i]) != 0)
        return btf_fail(err, BTF_ERR_IO, "budget: cannot restore %s", s->dir[i]);
    return BTF_OK;
}

/* Prefixes lo..hi of p (clipped to 1..n_chunks) measured as btf eval measures them,
 * in one pass, into lab[n] and rmse[n] (NAN until measured). */
static btf_result btf__budget_exact_span(const btf__search *s, btf_package *p, int lo, int hi, double *lab,
                                         double *rmse, btf_error *err)
{
    int ns[3], count = 0;
    for (int n = lo < 1 ? 1 : lo; n <= hi && n <= p->n_chunks && count < 3; n++)
        if (isnan(lab[n]))
            ns[count++] = n;
    btf_metrics m[3];
    btf_result r = count ? btf_package_compare_prefixes(p, ns, count, s->src, m, err) : BTF_OK;
    for (int i = 0; r == BTF_OK && i < count; i++)
        lab[ns[i]] = m[i].lab_thesis, rmse[ns[i]] = m[i].rmse;
    return r;
}

/* Under an error target, the written winner's prefix measured as btf eval measures
 * it (every texel and pair; the manifest's errors are a texel sample's, which can
 * land a little either side of the truth): the fewest chunks that meet the target
 * that way, found from the sample's choice up or down, the chunk counts around it
 * three at a time in one pass; with none left it is reported unmet (the search then
 * tries finer steps). */
static btf_result btf__budget_exact(btf__search *s, btf_budget_choice *got, int *met, btf_error *err)
{
    if (s->b->max_error <= 0 || !*met || got->n_chunks < 1)
        return BTF_OK;
    btf_package *p = NULL;
    btf_result r = btf_package_read(s->dir[s->best], 0, &p, err);
    if (r != BTF_OK)
        return r;
    size_t slots = (size_t)p->n_chunks + 1; /* by chunk count */
    double *lab = malloc(slots * sizeof(double)), *rmse = malloc(slots * sizeof(double));
    if (!lab || !rmse)
        r = btf_fail(err, BTF_ERR_NOMEM, "budget: out of memory");
    for (size_t i = 0; r == BTF_OK && i < slots; i++)
        lab[i] = rmse[i] = NAN;
    int n = got->n_chunks < p->n_chunks ? got->n_chunks : p->n_chunks;
    if (r == BTF_OK)
        r = btf__budget_exact_span(s, p, n - 1, n + 1, lab, rmse, err);
    while (r == BTF_OK && lab[n] > s->b->max_error && n < p->n_chunks) /* up: the sample said met too soon */
        if (isnan(lab[++n]))
            r = btf__budget_exact_span(s, p, n, n + 2, lab, rmse, err);
    while (r == BTF_OK && lab[n] <= s->b->max_error && n > 1) { /* down: the sample said met too late */
        if (isnan(lab[n - 1]))
            r = btf__budget_exact_span(s, p, n - 3, n - 1, lab, rmse, err);
        if (r != BTF_OK || !(lab[n - 1] <= s->b->max_error))
            break;
        n--;
    }
    if (r == BTF_OK) {
        *met = lab[n] <= s->b->max_error;
        got->n_chunks = n, got->lab = lab[n], got->rmse = rmse[n], got->bytes = btf__prefix_bytes(p, n);
    }
    free(lab), free(rmse);
    btf_package_free(p);
    return r;
}

/* The candidates were measured on a window or only estimated (rd): the best one is
 * compressed from the whole material now (on the whole material with rd, from its
 * kept model and ladder: the same steps), and its best prefix read off the files as
 * written (fitted again when they overshoot the budget: btf__budget_refit). */
static btf_result btf__budget_write_best(btf__search *s, btf_error *err)
{
    btf_budget_choice got;
    int met = 0;
    btf_result r = btf__budget_run(s, s->best, 1, &got, &met, err);
    if (r == BTF_OK && got.n_chunks > 0)
        r = btf__budget_refit(s, &got, &met, err);
    if (r == BTF_OK && got.n_chunks == 0)
        r = btf_fail(err, BTF_ERR_RANGE, "budget: %lld bytes cannot hold even the first chunk as written (%lld)",
                     s->b->max_bytes, got.bytes);
    if (r == BTF_OK)
        s->rs.candidate[s->best] = got, s->best_met = met;
    return r;
}

/* 1 when candidate c may do better with more components: it keeps every one it has
 * (the count stopped it, not the budget), the caller fixed no count, and under an
 * error target it misses the target (one that meets it with all its chunks would cut
 * more components off at the same place), by at most reach times it. */
static int btf__budget_short(const btf__search *s, int c, double reach)
{
    double e = s->rs.candidate[c].lab, t = s->b->max_error;
    return s->all_kept[c] && s->b->max_components <= 0 && (t <= 0 || (e > t && e <= reach * t));
}

/* 1 when the larger k of candidate c, which lost keeping every component, may still
 * win with more: under a byte budget its error is within BTF__BUDGET_GROW_GAIN of the
 * best's (under an error target btf__budget_short's reach decides). */
static int btf__budget_may_catch(const btf__search *s, int c)
{
    return s->b->max_error > 0 || s->best < 0 ||
           s->rs.candidate[c].lab * BTF__BUDGET_GROW_GAIN < s->rs.candidate[s->best].lab;
}

/* Candidate c measured again with half as many components again, rounded up to a
 * multiple of 4 (16, 24, 36, 56, 64: the renderer reads 4 per texel; up to
 * BTF_BUDGET_MAX_COMPONENTS and what its blocks hold), as the best only with more
 * chunks kept than c and by BTF__BUDGET_GROWN_EDGE; its index into *i, -1 when the
 * blocks hold no more. */
static btf_result btf__budget_grown(btf__search *s, int c, int *i, btf_error *err)
{
    btf_budget_choice was = s->rs.candidate[c];
    int n = (was.components * 3 / 2 + 3) / 4 * 4;
    n = n < BTF_BUDGET_MAX_COMPONENTS ? n : BTF_BUDGET_MAX_COMPONENTS;
    n = btf__fit_components(s->src, s->pca, was.k, n);
    *i = -1;
    if (n <= was.components || s->rs.n_candidates >= BTF_BUDGET_MAX_CANDIDATES - 2)
        return BTF_OK;
    for (int j = 0; j < s->rs.n_candidates; j++) { /* measured already (grown in the walk): as it was */
        const btf_budget_choice *m = &s->rs.candidate[j];
        if (m->k == was.k && m->components == n && m->center == was.center && m->rd_fit == was.rd_fit) {
            *i = j;
            return BTF_OK;
        }
    }
    *i = s->rs.n_candidates;
    s->rs.candidate[*i] = (btf_budget_choice){.k = was.k, .components = n, .rd_fit = was.rd_fit, .center = was.center};
    return btf__budget_eval(s, *i, was.n_chunks + 1, BTF__BUDGET_GROWN_EDGE, err);
}

/* Under an error target, 1 when candidate c (not the best) misses it keeping every
 * component it has (btf__budget_short, any reach), in fewer bytes than the best takes:
 * with more components it may meet it in fewer bytes than the best needs. */
static int btf__budget_cheaper(const btf__search *s, int c)
{
    return s->b->max_error > 0 && s->best >= 0 && s->best != c && btf__budget_short(s, c, HUGE_VAL) &&
           s->rs.candidate[c].bytes < s->rs.candidate[s->best].bytes;
}

/* Under an error target, 1 when candidate c (missing it) may meet it with more
 * components in fewer bytes than the best: the growth steps it needs at a ratio rl of
 * its error per step, each multiplying its bytes by rb, end under the best's bytes. */
static int btf__budget_worth_growing(const btf__search *s, int c, double rl, double rb)
{
    const btf_budget_choice *x = &s->rs.candidate[c], *b = &s->rs.candidate[s->best];
    if (!(rl > 0.0 && rl < 1.0) || !(rb > 1.0) || !(x->lab > 0.0))
        return 0;
    double m = ceil(log(s->b->max_error / x->lab) / log(rl));
    return (double)x->bytes * pow(rb, m > 1.0 ? m : 1.0) < (double)b->bytes;
}

/* Candidate c, which missed an error target with fewer bytes than the best
 * (btf__budget_cheaper), grown (btf__budget_grown) while each growth still does, lowers
 * the error by BTF__BUDGET_GROWN_EDGE and may meet the target under the best's bytes
 * (btf__budget_worth_growing: at first at BTF__BUDGET_GROW_LAB and _BYTES a step, then
 * at its last step's ratios). The knit 3652 at 256x256 under CIELab 2.4 missed it at
 * k 27 with 16 components in 612,546 bytes (3.127), where k 9 took 2,167,531 with 16
 * and met it with 24 in 2,636,332; k 41 met it with 56 in 1,141,602 (2.393). *g: the
 * last growth, -1 without one. */
static btf_result btf__budget_grow_cheaper(btf__search *s, int c, int *g, btf_error *err)
{
    btf_result r = BTF_OK;
    double rl = BTF__BUDGET_GROW_LAB, rb = BTF__BUDGET_GROW_BYTES;
    *g = -1;
    for (int at = c, t = 0; r == BTF_OK && t < BTF_BUDGET_MAX_GROW && btf__budget_cheaper(s, at) &&
                            btf__budget_worth_growing(s, at, rl, rb);
         t++) {
        int next = -1;
        r = btf__budget_grown(s, at, &next, err);
        if (r != BTF_OK || next < 0 || next == at)
            break;
        *g = next;
        const btf_budget_choice *a = &s->rs.candidate[at], *n = &s->rs.candidate[next];
        if (s->best == next || n->lab > BTF__BUDGET_GROWN_EDGE * a->lab)
            break; /* it won, or more components did not help */
        rl = n->lab / a->lab, rb = a->bytes > 0 ? (double)n->bytes / (double)a->bytes : rb;
        at = next;
    }
    return r;
}

/* While the best candidate keeps every component it has (and misses an error
 * target: btf__budget_short), it is tried again with more (btf__budget_grown);
 * stops when the larger one does not win. Steps of half as
 * many again, not doubling: with the steps fitted to the bytes the error is not
 * monotonic in the count, so a doubling can step over the best. The larger one wins
 * only with more chunks kept, not by a lower error alone: with as many chunks it
 * holds about the same components, and its edge is noise of the window. */
static btf_result btf__budget_grow(btf__search *s, btf_error *err)
{
    btf_result r = BTF_OK;
    for (int g = 0; r == BTF_OK && g < BTF_BUDGET_MAX_GROW && s->best >= 0 && btf__budget_short(s, s->best, HUGE_VAL); g++) {
        int was = s->best, i = -1;
        r = btf__budget_grown(s, was, &i, err);
        if (i < 0 || s->best == was)
            break; /* the blocks hold no more, or the larger one lost */
    }
    return r;
}

/* Where the PCA fits clipped samples (btf_pca.c: a sample at 0 or 1 may lie beyond
 * it), it fills them from all C components, and with more components than the
 * chunks a budget keeps that fit follows the noise of the terms cut off. So under a
 * byte budget, while the best keeps n < C chunks it is measured again with n
 * components, the fit at the rank it keeps, and stops when that does not win by
 * BTF__BUDGET_GROWN_EDGE. The thesis wool at 256x256 at the thesis format's bytes,
 * k 3 centred, whole material: 16 components kept 9 chunks at CIELab 0.1745, 10 kept
 * 9 at 0.1694, 9 kept 8 at 0.1681 (doc/performance.md section 3). Not under an error
 * target, whose fitted steps (btf__budget_fit_error) trade the spare components for
 * coarser steps: the tiles 3621 at 64x64 shrunk from 16 to 11 components by 0.4% of
 * the bytes, and the fitted steps then found nothing (92.1 KB against 65.3 KB). */
static btf_result btf__budget_shrink(btf__search *s, btf_error *err)
{
    btf_result r = BTF_OK;
    if (!s->clipped)
        return r;
    for (int g = 0; r == BTF_OK && g < BTF_BUDGET_MAX_SHRINK && s->best >= 0 &&
                    s->rs.n_candidates < BTF_BUDGET_MAX_CANDIDATES - 2;
         g++) {
        const btf_budget_choice was = s->rs.candidate[s->best];
        if (was.n_chunks < 1 || was.n_chunks >= was.components || was.n_chunks >= s->rank[s->best])
            break; /* every component kept, or every one its model holds (fitted at that rank already) */
        int i = s->rs.n_candidates, prev = s->best;
        s->rs.candidate[i] =
            (btf_budget_choice){.k = was.k, .components = was.n_chunks, .rd_fit = was.rd_fit, .center = was.center};
        r = btf__budget_eval(s, i, 1, BTF__BUDGET_GROWN_EDGE, err);
        if (s->best == prev)
            break;
    }
    return r;
}

/* Under an error target, the best candidate's model (its k, components, centring)
 * with its steps fitted to a byte budget instead of the equal-noise error (rd_fit:
 * the truncation and the quantisation traded at one slope), the budget bisected for
 * the fewest bytes whose best prefix still meets the target; a trial that does takes
 * the best's place, and s->fit_bytes keeps its budget for the final write. Three
 * misses from the top (no win by 1/16 of the bytes) end it, unless the last came
 * within BTF__BUDGET_FIT_NEAR of the target. Only the winning trial
 * stays in the record. On the generated tiles 3621 at 64x64 under the thesis
 * format's error the equal-noise steps took 92.5 KB at k 41 with 16 components,
 * fitted steps of the same model 66 KB (doc/performance.md section 3). Not on a
 * window (a side of 128 texels or more): there the tiles 3631 at 256x256 came out at
 * 152.8 KB in 281 s of CPU against the equal-noise steps' 127.6 KB in 85 s (the
 * budget found on the window did not carry to the whole material; not looked into). */
static btf_result btf__budget_fit_error(btf__search *s, btf_error *err)
{
    if (!s->po.rd || s->b->max_error <= 0 || s->best < 0 || !s->best_met || s->screen != s->src)
        return BTF_OK;
    const btf_budget_choice b = s->rs.candidate[s->best];
    const int first = s->rs.n_candidates;
    long long hi = b.bytes, lo = hi / 2, won = 0;
    int near = 0; /* the last trial missed by at most BTF__BUDGET_FIT_NEAR */
    btf_result r = BTF_OK;
    for (int t = 0; r == BTF_OK && t < BTF__BUDGET_FIT_TRIALS && first + t < BTF_BUDGET_MAX_CANDIDATES - 2 &&
                    (won || t < 3 || near);
         t++) {
        int i = first + t, was = s->best;
        s->fit_bytes = lo + (hi - lo) / 2;
        s->rs.candidate[i] = (btf_budget_choice){.k = b.k, .components = b.components, .rd_fit = 1, .center = b.center};
        r = btf__budget_eval(s, i, 1, 1.0, err);
        near = s->rs.candidate[i].n_chunks > 0 && s->rs.candidate[i].lab <= BTF__BUDGET_FIT_NEAR * s->b->max_error;
        if (s->best != was)
            won = s->fit_bytes, hi = s->fit_bytes;
        else
            lo = s->fit_bytes;
    }
    if (won && s->best != first) { /* the winner into the first trial's slot */
        s->rs.candidate[first] = s->rs.candidate[s->best], s->all_kept[first] = s->all_kept[s->best];
        s->rank[first] = s->rank[s->best];
        s->best = first;
    }
    s->rs.n_candidates = first + (won ? 1 : 0);
    s->fit_bytes = won;
    return r;
}

/* The candidates are measured on the centre window of half the material's width
 * and height where a side has at least BTF_BUDGET_SCREEN_MIN texels (a quarter of
 * the texels: the PCA, the ladders, the quantisation pass and the files cost about
 * a quarter), its texture bytes counted whole texels / window texels times over and
 * its CIELab subsample as many times smaller (the same texel stride); the winner is
 * then compressed from the whole material (btf__budget_write_best). */
static btf_result btf__budget_screen(btf__search *s, btf_error *err)
{
    int w = s->src->width, h = s->src->height;
    int cw = w >= BTF_BUDGET_SCREEN_MIN ? w / 2 : w, ch = h >= BTF_BUDGET_SCREEN_MIN ? h / 2 : h;
    s->rs.screen_width = w, s->rs.screen_height = h;
    if ((long)cw * ch == (long)w * h || s->b->full_search)
        return BTF_OK;
    btf *win = NULL;
    btf_result r = btf_crop(s->src, (w - cw) / 2, (h - ch) / 2, cw, ch, &win, err);
    if (r == BTF_OK) {
        s->screen = win, s->screen_scale = (double)w * h / ((double)cw * ch);
        s->rs.screen_width = cw, s->rs.screen_height = ch;
    }
    return r;
}

/* Under an error target, 1 when the walk need not measure the larger k: the best so
 * far keeps every component it has and misses the target by more than
 * BTF__BUDGET_GROW_REACH, and its blocks nest in k's (consecutive views, k a multiple
 * of its k). Each block of k is then a union of the best's blocks, whose own PCA fits
 * each of them at least as well with as many components, so k misses the target by
 * more and would be neither the best nor grown (btf__budget_short). The thesis
 * corduroy at 64x64 under its format's error (0.4073): k 9 at CIELab 0.765, k 27
 * 1.052. */
static int btf__budget_beyond_reach(const btf__search *s, int k, int n)
{
    if (s->b->max_error <= 0 || s->best < 0 || !s->all_kept[s->best])
        return 0;
    const btf_budget_choice *b = &s->rs.candidate[s->best];
    int nested = s->pca.grouping == BTF_GROUP_DEFAULT || s->pca.grouping == BTF_GROUP_CONSECUTIVE;
    return nested && k % b->k == 0 && n <= b->components && b->center == s->pca.center &&
           b->lab > BTF__BUDGET_GROW_REACH * s->b->max_error;
}

/* 1 when candidate c took the place of the best before it, prev, by meeting the error
 * target prev missed, and prev may do better with more components
 * (btf__budget_short within BTF__BUDGET_GROW_REACH): prev at its count never had the
 * chance to meet it. */
static int btf__budget_overtaken(const btf__search *s, int c, int prev, int prev_met)
{
    return s->best == c && prev >= 0 && s->b->max_error > 0 && !prev_met && s->best_met &&
           btf__budget_short(s, prev, BTF__BUDGET_GROW_REACH);
}

/* Candidates k = ks[0 .. nk) measured with n components (fit: steps fitted to the
 * bytes), in order; with the default walk (btf__budget_prunes) the larger ks stop
 * at the first that does not beat the best, and the smaller ones are measured only
 * when no larger one won, stopping the same way but for the last (k 1), measured
 * whenever the walk goes down: the generated stone 3653 at 256x256 at the thesis
 * format's bytes took k 1 at CIELab 0.710 before k 5 was in the walk, and k 5 at
 * 0.863 since (k 3 lost to k 5 and ended the walk). A larger k that loses while keeping
 * every component it has and missing an error target by at most
 * BTF__BUDGET_GROW_REACH (btf__budget_short) is measured once more with more
 * (btf__budget_grown) before it counts as lost: blocks of more views
 * need more components for the same error (the generated stone at 64x64: k 27 loses
 * to k 9 at 16 components and wins at 24). Likewise the best before a candidate that
 * takes its place by meeting an error target it missed (btf__budget_overtaken): the
 * knit at 256x256 under CIELab 2.4 kept all 16 components at k 9 and missed by 10%,
 * and k 3 met it with 2.1x the bytes. A smaller k that takes the best's place keeping
 * every component (within the same reach of an error target) is grown while it wins
 * (btf__budget_grow) before the next smaller k: at the thesis format's bytes the
 * tiles 3621 at 64x64, k 5 with 16 components lost to k 3 with 16, and won with 36. */
static btf_result btf__budget_walk(btf__search *sr, const int *ks, int nk, int n, int fit, btf_error *err)
{
    int prune = btf__budget_prunes(sr->b), up_won = 0, up_lost = 0, down_lost = 0;
    btf_result r = BTF_OK;
    for (int i = 0; r == BTF_OK && i < nk; i++) {
        int up = ks[i] > ks[0], down = ks[i] < ks[0], last = i == nk - 1;
        if (prune && ((up && up_lost) || (down && (up_won || (down_lost && !last)))))
            continue;
        if (prune && up && btf__budget_beyond_reach(sr, ks[i], n)) {
            up_lost = 1; /* it would lose: the walk goes down */
            continue;
        }
        int c = sr->rs.n_candidates, prev = sr->best, prev_met = sr->best_met;
        sr->rs.candidate[c] = (btf_budget_choice){.k = ks[i], .components = n, .rd_fit = fit, .center = sr->pca.center};
        r = btf__budget_eval(sr, c, 0, 1.0, err);
        int g = -1, gp = -1; /* a larger k that lost keeping all its components: once more with more;
                              * gp: the overtaken best grown (when it wins, c did not) */
        if (r == BTF_OK && i > 0 && btf__budget_cheaper(sr, c))
            r = btf__budget_grow_cheaper(sr, c, &g, err); /* it may meet the target in fewer bytes */
        else if (r == BTF_OK && up && sr->best != c && btf__budget_short(sr, c, BTF__BUDGET_GROW_REACH) &&
                 btf__budget_may_catch(sr, c))
            r = btf__budget_grown(sr, c, &g, err);
        else if (r == BTF_OK && btf__budget_overtaken(sr, c, prev, prev_met))
            r = btf__budget_grown(sr, prev, &gp, err);
        else if (r == BTF_OK && down && sr->best == c && btf__budget_short(sr, c, BTF__BUDGET_GROW_REACH))
            r = btf__budget_grow(sr, err); /* a smaller k that won: grown while it wins, before the next */
        int won = sr->best == c || (g >= 0 && sr->best == g) || (gp < 0 && sr->best > c);
        up_won |= up && won, up_lost |= up && !won, down_lost |= down && !won;
    }
    return r;
}

btf_result btf_budget_compress(const btf *src, const btf_pca_options *pca, const btf_package_options *opt,
                               const btf_budget *budget, const char *out, btf_budget_result *res, btf_error *err)
{
    return btf_budget_compress_with(src, pca, opt, NULL, budget, out, res, err);
}

/* 1 when a answers an error target better than b: it meets it and b does not, both
 * meet it and a with fewer bytes, or neither does and a with less error. */
static int btf__budget_better(const btf_budget_result *a, const btf_budget_result *b)
{
    if (a->met != b->met)
        return a->met;
    return a->met ? a->bytes < b->bytes : a->lab < b->lab;
}

/* Among the first n candidates, the best of another k than the best's (uncentred,
 * with a prefix that answers the budget as the best's does) when it comes within
 * BTF__BUDGET_RUNNER_UP of the best; -1 otherwise. */
static int btf__budget_runner_up(const btf__search *s, int n)
{
    const btf_budget_choice *b = &s->rs.candidate[s->best];
    double t = s->b->max_error;
    int ru = -1;
    for (int i = 0; i < n; i++) {
        const btf_budget_choice *c = &s->rs.candidate[i];
        int met = t > 0 ? c->lab <= t : c->n_chunks > 0;
        if (i == s->best || c->k == b->k || c->center != BTF_CENTER_DEFAULT || c->n_chunks == 0 || met != s->best_met)
            continue;
        double v = t > 0 && met ? (double)c->bytes : c->lab, bv = t > 0 && met ? (double)b->bytes : b->lab;
        double rv = ru < 0 ? HUGE_VAL : t > 0 && met ? (double)s->rs.candidate[ru].bytes : s->rs.candidate[ru].lab;
        if (v <= BTF__BUDGET_RUNNER_UP * bv && v < rv)
            ru = i;
    }
    return ru;
}

/* The centred retry (the PCA less each texel's mean; on a window it must win by
 * BTF_BUDGET_SCREEN_EDGE) of candidate c, as candidate n. */
static btf_result btf__budget_centred(btf__search *s, int c, int n, btf_error *err)
{
    s->rs.candidate[n] = s->rs.candidate[c];
    s->rs.candidate[n].center = BTF_CENTER_ROW;
    return btf__budget_eval(s, n, 0, s->screen != s->src ? 1.0 - BTF_BUDGET_SCREEN_EDGE : 1.0, err);
}

/* One search at opt's steps (btf_budget_compress_with does one or more); finer: 0,
 * or the texture noise of a finer search, which the result and its record state. */
static btf_result btf__budget_search_once(const btf *src, const btf_pca_options *pca, const btf_package_options *opt,
                                          const btf_package_channel *hook, const btf_budget *budget, float finer,
                                          const char *out, btf_budget_result *res, btf_error *err)
{
    btf_budget_result rs;
    memset(&rs, 0, sizeof rs);
    if (!src || !budget || !out || strlen(out) > 4000 || (budget->max_bytes > 0) == (budget->max_error > 0))
        return btf_fail(err, BTF_ERR_ARG, "budget: give exactly one of a byte budget and an error target");
    btf_result r = btf_fs_replaceable(out, btf_manifest_owns_dir, NULL, err);
    btf_package_options po = opt ? *opt : (btf_package_options){0};
    int thumbnail = po.thumbnail; /* of the chosen package once it is cut, not of every candidate */
    po.thumbnail = 0;
    btf__search *sr = calloc(1, sizeof *sr);
    if (!sr)
        return btf_fail(err, BTF_ERR_NOMEM, "budget: out of memory");
    *sr = (btf__search){.src = src, .screen = src, .screen_scale = 1.0, .pca = pca ? *pca : (btf_pca_options){0},
                        .po = po, .b = budget, .out = out, .best = -1};
    if (hook)
        sr->hook.write_hook = hook->write_hook, sr->hook.hook_ctx = hook->hook_ctx;
    if (r == BTF_OK)
        r = btf__budget_screen(sr, err);
    sr->clipped = budget->max_bytes > 0 && sr->pca.clipped != BTF_CLIPPED_KEEP &&
                  btf_pca_clipped_share(sr->screen) >= BTF_PCA_CLIPPED_MIN_SHARE;
    int ks[BTF_BUDGET_MAX_K], nk = btf__budget_ks(budget, src->views.n_dirs, ks);
    int fit = po.rd && budget->max_bytes > 0; /* version 3: steps fitted to the bytes */
    int n0 = budget->max_components > 0 ? budget->max_components : BTF_BUDGET_COMPONENTS;
    if (r == BTF_OK)
        r = btf__budget_walk(sr, ks, nk, n0, fit, err);
    int nt = sr->rs.n_candidates;
    if (r == BTF_OK && sr->best >= 0 && sr->pca.center == BTF_CENTER_DEFAULT) { /* the best, centred */
        /* and a close runner-up of another k; not when levels follow, whose cost the
         * candidates' bytes leave out (tiles 3641 at 128x128 under CIELab 2.4 with
         * --levels 4: k 41 centred won by its version-3 bytes and took 185,685 bytes
         * with its levels, against 171,428 at k 81) */
        int ru = po.levels ? -1 : btf__budget_runner_up(sr, nt);
        r = btf__budget_centred(sr, sr->best, nt, err);
        if (r == BTF_OK && ru >= 0)
            r = btf__budget_centred(sr, ru, nt + 1, err);
    }
    if (r == BTF_OK && budget->max_components <= 0)
        r = btf__budget_grow(sr, err);
    if (r == BTF_OK)
        r = btf__budget_shrink(sr, err);
    if (r == BTF_OK)
        r = btf__budget_fit_error(sr, err);
    if (r == BTF_OK && sr->best >= 0 && (po.rd || sr->screen != src))
        r = btf__budget_write_best(sr, err);
    if (r == BTF_OK && sr->best >= 0)
        r = btf__budget_exact(sr, &sr->rs.candidate[sr->best], &sr->best_met, err);
    if (r == BTF_OK && sr->best >= 0 && !sr->best_met && sr->fit_bytes > 0) {
        /* fitted steps that miss the target as written (every texel, every chunk): once more with 5% more bytes */
        sr->fit_bytes += sr->fit_bytes / 20;
        r = btf__budget_write_best(sr, err);
        if (r == BTF_OK)
            r = btf__budget_exact(sr, &sr->rs.candidate[sr->best], &sr->best_met, err);
    }
    rs = sr->rs;
    int best = sr->best, best_met = sr->best_met;
    if (r == BTF_OK && best < 0) {
        long long need = rs.candidate[0].bytes;
        for (int i = 1; i < rs.n_candidates; i++)
            need = rs.candidate[i].bytes < need ? rs.candidate[i].bytes : need;
        r = btf_fail(err, BTF_ERR_RANGE, "budget: %lld bytes cannot hold even the first chunk (the smallest needs %lld)",
                     budget->max_bytes, need);
    }
    if (r == BTF_OK) {
        const btf_budget_choice *c = &rs.candidate[best];
        rs.k = c->k, rs.components = c->components, rs.rd_fit = c->rd_fit, rs.center = c->center;
        rs.n_chunks = c->n_chunks, rs.bytes = c->bytes;
        rs.lab = c->lab, rs.rmse = c->rmse, rs.met = best_met;
        rs.tex_noise = finer;
        r = btf__budget_finish(sr->dir[best], budget, &rs, err);
        if (r == BTF_OK && thumbnail > 0)
            r = btf_package_thumbnail(sr->dir[best], thumbnail, err);
        if (r == BTF_OK)
            r = btf_fs_replace_dir(sr->dir[best], out, btf_manifest_owns_dir, NULL, err);
    }
    for (int i = 0; i < rs.n_candidates; i++)
        btf_fs_rmtree(sr->dir[i], NULL);
    for (int i = 0; i < 2; i++)
        btf_pca_model_free(sr->model[i]), btf_rd_ladder_free(&sr->ladder[i]), btf_rd_result_free(&sr->rd[i]);
    free(sr->final_tex), free(sr->tex_fix);
    if (sr->screen != src)
        btf_free((btf *)sr->screen);
    free(sr);
    if (res)
        *res = rs;
    return r;
}

btf_result btf_budget_compress_with(const btf *src, const btf_pca_options *pca, const btf_package_options *opt,
                                    const btf_package_channel *hook, const btf_budget *budget, const char *out,
                                    btf_budget_result *res, btf_error *err)
{
    btf_budget_result rs, alt;
    memset(&rs, 0, sizeof rs);
    btf_package_options po = opt ? *opt : (btf_package_options){0};
    char name[BTF_PACKAGE_NAME_MAX], tmp[BTF_FS_PATH_MAX];
    if (!po.name && out) { /* the material is OUT's, not its temporaries' */
        const char *slash = strrchr(out, '/');
        snprintf(name, sizeof name, "%s", slash && slash[1] ? slash + 1 : out);
        po.name = name;
    }
    btf_result r = btf__budget_search_once(src, pca, &po, hook, budget, 0.0f, out, &rs, err);
    /* An error target below what the default steps reach at any k and component
     * count: the search again at half and a quarter of the texture noise (finer steps),
     * each into OUT.finer-PID, which replaces OUT when it does better (btf__budget_better). */
    float noise = po.tex_noise > 0.0f ? po.tex_noise : BTF_PACKAGE_TEX_NOISE;
    int finer = r == BTF_OK && budget->max_error > 0 && !rs.met && po.tex_noise >= 0.0f;
    if (finer)
        snprintf(tmp, sizeof tmp, "%s.finer-%ld", out, (long)getpid());
    for (int i = 0; finer && r == BTF_OK && i < BTF_BUDGET_FINER; i++) {
        po.tex_noise = noise /= 2.0f;
        r = btf__budget_search_once(src, pca, &po, hook, budget, noise, tmp, &alt, err);
        if (r == BTF_OK && btf__budget_better(&alt, &rs) &&
            (r = btf_fs_replace_dir(tmp, out, btf_manifest_owns_dir, NULL, err)) == BTF_OK)
            rs = alt;
        btf_fs_rmtree(tmp, NULL);
    }
    if (res)
        *res = rs;
    return r;
}
