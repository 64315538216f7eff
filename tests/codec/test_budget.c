/* test_budget.c - room codec, suite "budget": compression to a byte budget or an
 * error target (codec/include/btf_budget.h), checked against packages compressed independently here. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "btf_budget.h"
#include "btf_fs.h"
#include "btf_gen.h"
#include "fixtures.h"

/* Generated tiles of size x size texels under 15 directions. */
static btf *material_of(int size)
{
    static const btf_ring r[3] = {{0.0f, 1, 0.0f}, {30.0f, 6, 0.0f}, {60.0f, 8, 0.0f}};
    return fx_material(BTF_GEN_TILES, size, r, 3);
}

static btf *material(void) { return material_of(16); }

/* The walk's candidates alone: the tiles' highlights are clipped at 1, and where the
 * PCA fits them the search also measures its best at the count it keeps
 * (btf__budget_shrink, tested on its own below). */
static const btf_pca_options *walk_only(void)
{
    static const btf_pca_options po = {.clipped = BTF_CLIPPED_KEEP};
    return &po;
}

/* Bytes on disk of a package: every regular file in dir. */
static long long dir_bytes(const char *dir)
{
    DIR *d = opendir(dir);
    long long n = 0;
    char path[512];
    for (struct dirent *e; d && (e = readdir(d));) {
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        n += e->d_name[0] != '.' && btf_fs_size(path) > 0 ? btf_fs_size(path) : 0;
    }
    if (d)
        closedir(d);
    return n;
}

/* An independent package of k at 16 components: its chunk bytes and prefix errors. */
static btf_package *reference(const btf *src, int k, const char *dir)
{
    btf_pca_options po = {0};
    po.k = k, po.components = 16;
    btf_error err = {0};
    cr_assert_eq(btf_package_compress(src, &po, NULL, dir, NULL, &err), BTF_OK, "%s", err.msg);
    btf_package *p = NULL;
    cr_assert_eq(btf_package_read(dir, 1, &p, &err), BTF_OK, "%s", err.msg);
    return p;
}

Test(budget, max_bytes_is_met_and_no_prefix_of_the_same_k_does_better)
{
    char dir[64], out[128], ref[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/wool", dir);
    snprintf(ref, sizeof ref, "%s/ref", dir);
    btf *src = material();
    btf_budget b = {0};
    b.max_bytes = 40000, b.k[0] = 3, b.n_k = 1;
    btf_budget_result res;
    btf_error err = {0};
    cr_assert_eq(btf_budget_compress(src, NULL, NULL, &b, out, &res, &err), BTF_OK, "%s", err.msg);
    cr_expect(res.met && res.k == 3 && res.n_chunks >= 1);
    cr_expect_eq(dir_bytes(out), res.bytes, "on disk %lld, reported %lld", dir_bytes(out), res.bytes);
    cr_expect_leq(res.bytes, b.max_bytes);
    btf_package *got = NULL, *p = reference(src, 3, ref);
    cr_assert_eq(btf_package_read(out, 0, &got, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(got->n_chunks, res.n_chunks);
    cr_expect_str_eq(got->name, "wool");
    cr_expect(got->budget && strstr(got->budget, "\"max_bytes\":40000"), "%s", got->budget ? got->budget : "none");
    long long files = 0;
    for (int n = 1; n <= p->n_chunks; n++) { /* every prefix of the same k within the budget is no better */
        files += p->chunk[n - 1].bytes;
        if (files + 2000 < b.max_bytes - 4000) /* clearly inside even with a larger manifest */
            cr_expect_geq(p->chunk[n - 1].lab + 1e-9, res.lab, "prefix %d: Lab %.4f < chosen %.4f", n,
                          p->chunk[n - 1].lab, res.lab);
    }
    btf_package_free(got), btf_package_free(p);
    btf_free(src);
    fx_rmtree(dir);
}

Test(budget, max_error_is_reached_with_the_fewest_chunks)
{
    char dir[64], out[128], ref[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/p", dir);
    snprintf(ref, sizeof ref, "%s/ref", dir);
    btf *src = material();
    btf_package *p = reference(src, 1, ref);
    double target = p->chunk[p->n_chunks / 2].lab; /* reachable at about half the chunks */
    btf_budget b = {0};
    b.max_error = target, b.k[0] = 1, b.n_k = 1;
    btf_pca_options po = {0}; /* the reference's centring: no centred retry */
    po.center = BTF_CENTER_NONE;
    btf_budget_result res;
    btf_error err = {0};
    cr_assert_eq(btf_budget_compress(src, &po, NULL, &b, out, &res, &err), BTF_OK, "%s", err.msg);
    cr_expect(res.met);
    cr_expect_leq(res.lab, target);
    int first = 0;
    while (first < p->n_chunks && p->chunk[first].lab > target)
        first++;
    cr_expect_eq(res.n_chunks, first + 1, "chose %d chunks, the first prefix reaching %.4f has %d", res.n_chunks,
                 target, first + 1);
    btf_package_free(p);
    btf_free(src);
    fx_rmtree(dir);
}

/* Under an error target the chosen prefix is the fewest chunks whose error, as btf
 * eval measures it (every texel and pair, here btf_compare of the whole decode),
 * meets the target, and the record states that error: at 32x32 the writer's error
 * sample is every 2nd texel in x and y, which lands a little either side of it. */
Test(budget, an_error_target_is_met_as_every_texel_measures_it)
{
    char dir[64], out[128], ref[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/p", dir);
    snprintf(ref, sizeof ref, "%s/ref", dir);
    btf *src = material_of(32);
    btf_package *p = reference(src, 1, ref);
    for (int t = 2; t < p->n_chunks - 2; t += 3) {
        btf_budget b = {0};
        b.max_error = p->chunk[t].lab, b.k[0] = 1, b.n_k = 1;
        btf_pca_options po = {0};
        po.center = BTF_CENTER_NONE;
        btf_budget_result res;
        btf_error err = {0};
        cr_assert_eq(btf_budget_compress(src, &po, NULL, &b, out, &res, &err), BTF_OK, "%s", err.msg);
        btf_package *got = fx_package(out, NULL, 0);
        btf *rec = NULL;
        btf_metrics m, fewer = {0};
        cr_assert_eq(btf_package_reconstruct(got, 0, &rec, &err), BTF_OK, "%s", err.msg);
        cr_assert_eq(btf_compare(src, rec, NULL, &m, &err), BTF_OK, "%s", err.msg);
        btf_free(rec);
        if (got->n_chunks > 1) {
            cr_assert_eq(btf_package_reconstruct(got, got->n_chunks - 1, &rec, &err), BTF_OK, "%s", err.msg);
            cr_assert_eq(btf_compare(src, rec, NULL, &fewer, &err), BTF_OK, "%s", err.msg);
            btf_free(rec);
        }
        cr_log_info("target %.5f: %d chunks, every texel %.5f (one fewer %.5f), the sample %.5f", b.max_error,
                    got->n_chunks, m.lab_thesis, fewer.lab_thesis, got->chunk[got->n_chunks - 1].lab);
        cr_expect(res.met);
        cr_expect_leq(m.lab_thesis, b.max_error, "target %.5f", b.max_error);
        cr_expect_float_eq(res.lab, m.lab_thesis, 1e-9 * m.lab_thesis, "the record: %.6f", res.lab);
        cr_expect(got->n_chunks == 1 || fewer.lab_thesis > b.max_error, "one chunk fewer: %.5f", fewer.lab_thesis);
        btf_package_free(got);
    }
    btf_package_free(p);
    btf_free(src);
    fx_rmtree(dir);
}

/* An error target below what the default steps reach (the least error of any prefix
 * of the reference, every component compressed at the same steps) is met by searching
 * again with finer steps, no temporary left behind; the record says which steps; a
 * target nothing can reach still ends, reported unmet with the least error tried (the
 * finest steps). */
Test(budget, max_error_below_the_default_steps_is_met_with_finer_ones)
{
    char dir[64], out[128], ref[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/p", dir);
    snprintf(ref, sizeof ref, "%s/ref", dir);
    btf *src = material();
    btf_pca_options po = {0};
    po.k = 1, po.components = 45, po.center = BTF_CENTER_NONE; /* 15 lights x 3: every component */
    btf_error err = {0};
    cr_assert_eq(btf_package_compress(src, &po, NULL, ref, NULL, &err), BTF_OK, "%s", err.msg);
    btf_package *p = NULL;
    cr_assert_eq(btf_package_read(ref, 1, &p, &err), BTF_OK, "%s", err.msg);
    double floor = p->chunk[0].lab; /* each component adds its steps' noise: the least error of any prefix */
    for (int i = 1; i < p->n_chunks; i++)
        floor = p->chunk[i].lab < floor ? p->chunk[i].lab : floor;
    btf_budget b = {0};
    b.max_error = 0.8 * floor, b.k[0] = 1, b.n_k = 1, b.max_components = 45;
    btf_budget_result res;
    cr_assert_eq(btf_budget_compress(src, &po, NULL, &b, out, &res, &err), BTF_OK, "%s", err.msg);
    cr_log_info("floor %.4f at the default steps; target %.4f met %d at tex_noise %.3f, Lab %.4f, %d chunks", floor,
                b.max_error, res.met, res.tex_noise, res.lab, res.n_chunks);
    cr_expect(res.met, "Lab %.4f, target %.4f", res.lab, b.max_error);
    cr_expect_leq(res.lab, b.max_error);
    cr_expect(res.tex_noise > 0.0f && res.tex_noise < BTF_PACKAGE_TEX_NOISE, "tex_noise %.3f", res.tex_noise);
    btf_package *got = NULL;
    cr_assert_eq(btf_package_read(out, 0, &got, &err), BTF_OK, "%s", err.msg);
    cr_expect(got->budget && strstr(got->budget, "\"tex_noise\""), "%s", got->budget ? got->budget : "none");
    btf_package_free(got);
    DIR *d = opendir(dir); /* the finer searches' packages are gone: only p and ref */
    int entries = 0;
    for (struct dirent *e; d && (e = readdir(d));)
        entries += e->d_name[0] != '.';
    if (d)
        closedir(d);
    cr_expect_eq(entries, 2, "%d entries in the test directory", entries);
    b.max_error = 1e-4; /* out of reach: the search ends */
    cr_assert_eq(btf_budget_compress(src, &po, NULL, &b, out, &res, &err), BTF_OK, "%s", err.msg);
    cr_expect(!res.met);
    cr_expect_float_eq(res.tex_noise, BTF_PACKAGE_TEX_NOISE / (1 << BTF_BUDGET_FINER), 1e-6);
    btf_package_free(p);
    btf_free(src);
    fx_rmtree(dir);
}

/* 1 when candidate c beats bc under b by the factor edge (within a byte budget: an
 * empty prefix loses, else the lower error; for an error target: meeting it, then
 * fewer bytes, else the lower error). */
static int beats_by(const btf_budget *b, const btf_budget_choice *c, const btf_budget_choice *bc, double edge)
{
    int met = c->lab <= b->max_error, best_met = bc->lab <= b->max_error;
    return b->max_bytes > 0 ? c->n_chunks > 0 && (bc->n_chunks == 0 || c->lab < edge * bc->lab)
           : met != best_met ? met
           : met             ? (double)c->bytes < edge * (double)bc->bytes
                             : c->lab < edge * bc->lab;
}

/* beats_by with no edge: how the walk ranks a candidate of another k. */
static int beats(const btf_budget *b, const btf_budget_choice *c, const btf_budget_choice *bc)
{
    return beats_by(b, c, bc, 1.0);
}

/* 1 when g, grown from was, takes the place of bc: with more chunks kept than was and
 * by 1% (the search's BTF__BUDGET_GROWN_EDGE). */
static int grown_beats(const btf_budget *b, const btf_budget_choice *g, const btf_budget_choice *was,
                       const btf_budget_choice *bc)
{
    return g->n_chunks > was->n_chunks && beats_by(b, g, bc, 0.99);
}

/* Of the candidates c[idx[0..n)] (best: the index of the best among them), the one
 * the search also retries centred: another k within 3% of the best (bytes for a met
 * error target, else the error), answering the budget as the best does; -1 when none. */
static int runner_up(const btf_budget *b, const btf_budget_choice *c, const int *idx, int n, int best)
{
    const btf_budget_choice *bb = &c[best];
    int ru = -1, bmet = b->max_bytes > 0 ? bb->n_chunks > 0 : bb->lab <= b->max_error;
    for (int j = 0; j < n; j++) {
        const btf_budget_choice *x = &c[idx[j]];
        int met = b->max_bytes > 0 ? x->n_chunks > 0 : x->lab <= b->max_error, by_bytes = b->max_error > 0 && met;
        double v = by_bytes ? (double)x->bytes : x->lab, bv = by_bytes ? (double)bb->bytes : bb->lab;
        double rv = ru < 0 ? HUGE_VAL : by_bytes ? (double)c[ru].bytes : c[ru].lab;
        if (idx[j] != best && x->k != bb->k && x->n_chunks > 0 && met == bmet && v <= 1.03 * bv && v < rv)
            ru = idx[j];
    }
    return ru;
}

/* The index of the best of the first n candidates of r as the search ranks them in
 * turn: a growth (the same k as the one before it) with grown_beats, else beats. */
static int walk_best(const btf_budget *b, const btf_budget_result *r, int n)
{
    int best = 0;
    for (int i = 1; i < n; i++) {
        const btf_budget_choice *c = &r->candidate[i];
        if (c->k == r->candidate[i - 1].k ? grown_beats(b, c, &r->candidate[i - 1], &r->candidate[best])
                                          : beats(b, c, &r->candidate[best]))
            best = i;
    }
    return best;
}

/* Candidate i of r in the test's log. */
static void log_candidate(const btf_budget_result *r, int i)
{
    const btf_budget_choice *c = &r->candidate[i];
    cr_log_info("candidate %d: k %d, %d components, %d chunks, CIELab %.4f, %lld bytes", i, c->k, c->components,
                c->n_chunks, c->lab, c->bytes);
}

/* The candidates of r before its first centred one measure the nk ks of order in
 * turn, each maybe followed by its growth (the same k again); their indices into idx,
 * their count returned. */
static int expect_ks(const btf_budget_result *r, const int *order, int nk, int *idx)
{
    int n = 0, at = 0;
    for (int i = 0; i < r->n_candidates && r->candidate[i].center != BTF_CENTER_ROW; i++) {
        if (i == 0 || r->candidate[i].k != r->candidate[i - 1].k) {
            cr_assert_lt(at, nk, "more ks than expected: k %d", r->candidate[i].k);
            cr_expect_eq(r->candidate[i].k, order[at], "k number %d: %d, expected %d", at, r->candidate[i].k,
                         order[at]);
            at++;
        }
        idx[n] = i, n++;
        log_candidate(r, i);
    }
    cr_expect_eq(at, nk, "%d ks measured", at);
    return n;
}

/* The default search without full_search walks the ks from the first (9): the larger
 * ones while each beats the best (one that loses keeping every component it has is
 * measured once more with more components first), then, only when no larger one won,
 * the smaller ones while each beats the best, and the smallest (k 1) in any case. all, the full search's candidates
 * (every default k in the walk's order, a larger one's growth after it, then the
 * centred retries), predicts which candidates it measures, their results (the same
 * settings measure the same) and its choice. */
static void expect_pruned_like(const btf *src, btf_budget b, const btf_budget_result *all, const char *out)
{
    b.full_search = 0;
    btf_budget_result res;
    btf_error err = {0};
    cr_assert_eq(btf_budget_compress(src, walk_only(), NULL, &b, out, &res, &err), BTF_OK, "%s", err.msg);
    int end = 0; /* all's walk: its candidates before the centred retry */
    while (end < all->n_candidates && all->candidate[end].center != BTF_CENTER_ROW)
        end++;
    int walk[BTF_BUDGET_MAX_CANDIDATES], n = 0, best = 0, up_won = 0, k0 = all->candidate[0].k, kmin = k0;
    for (int i = 0; i < end; i++)
        kmin = all->candidate[i].k < kmin ? all->candidate[i].k : kmin;
    for (int pass = 0, down_lost = 0; pass < 3; pass++) /* the first k, the larger ks, then the smaller ones */
        for (int i = 0, stop = pass == 2 && up_won; i < end && !stop; i++) {
            const btf_budget_choice *c = &all->candidate[i];
            if ((pass == 0) != (c->k == k0) || (pass == 1 && c->k < k0) || (pass == 2 && c->k > k0) ||
                (pass == 2 && down_lost && c->k != kmin)) /* after a smaller k lost: the smallest only */
                continue;
            int won = i == 0 || beats(&b, c, &all->candidate[best]);
            walk[n++] = i;
            best = won ? i : best;
            while (i + 1 < end && all->candidate[i + 1].k == c->k && c->k != k0) {
                /* its growth: a larger k's once when it lost, a smaller one's while it wins */
                int g = ++i;
                walk[n++] = g;
                if (grown_beats(&b, &all->candidate[g], &all->candidate[g - 1], &all->candidate[best]))
                    best = g, won = 1;
            }
            up_won |= pass == 1 && won;
            stop = pass == 1 && !won;
            down_lost |= pass == 2 && !won;
        }
    int ru = runner_up(&b, all->candidate, walk, n, best); /* retried centred too */
    cr_assert_eq(res.n_candidates, n + 1 + (ru >= 0), "%d candidates measured and the centred retries, got %d", n,
                 res.n_candidates);
    if (ru >= 0)
        cr_expect(res.candidate[n + 1].k == all->candidate[ru].k && res.candidate[n + 1].center == BTF_CENTER_ROW,
                  "the close runner-up's k (%d) centred", all->candidate[ru].k);
    for (int i = 0; i < n; i++) {
        const btf_budget_choice *want = &all->candidate[walk[i]];
        cr_expect_eq(res.candidate[i].k, want->k, "candidate %d: k %d, expected k %d", i, res.candidate[i].k, want->k);
        cr_expect_eq(res.candidate[i].components, want->components, "k %d: components", want->k);
        cr_expect_eq(res.candidate[i].bytes, want->bytes, "k %d: the same bytes", want->k);
        cr_expect_float_eq(res.candidate[i].lab, want->lab, 1e-12, "k %d: the same error", want->k);
    }
    cr_expect_eq(res.candidate[n].k, all->candidate[best].k, "the centred retry is of the best measured k");
    cr_expect_eq(res.candidate[n].center, BTF_CENTER_ROW);
}

Test(budget, candidates_are_compared_and_a_hopeless_budget_is_refused)
{
    char dir[64], out[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/p", dir);
    btf *src = material();
    btf_budget b = {0};
    b.max_bytes = 60000; /* 15 views: default candidates 9, 15 (every view), 5, 3, 1 */
    btf_budget_result res;
    btf_error err = {0};
    b.full_search = 1; /* every default k */
    cr_assert_eq(btf_budget_compress(src, walk_only(), NULL, &b, out, &res, &err), BTF_OK, "%s", err.msg);
    static const int order[5] = {9, 15, 5, 3, 1};
    int idx[BTF_BUDGET_MAX_CANDIDATES], n = expect_ks(&res, order, 5, idx);
    cr_expect_eq(res.n_candidates, n + 1 + (runner_up(&b, res.candidate, idx, n, walk_best(&b, &res, n)) >= 0),
                 "k 9, 15, 5, 3, 1 (a smaller k that wins grown), the best of them (and a close runner-up) "
                 "with row centring");
    for (int i = 0; i < res.n_candidates; i++)
        if (res.candidate[i].n_chunks > 0)
            cr_expect_geq(res.candidate[i].lab + 1e-12, res.lab, "k %d beats the choice", res.candidate[i].k);
    btf_budget_result all = res;
    expect_pruned_like(src, b, &all, out); /* here k 15 loses to k 9, k 3 beats it and k 1 beats k 3 */
    btf_budget e = {0};
    e.max_error = 0.8, e.full_search = 1;
    cr_assert_eq(btf_budget_compress(src, walk_only(), NULL, &e, out, &all, &err), BTF_OK, "%s", err.msg);
    n = expect_ks(&all, order, 5, idx);
    cr_assert_eq(all.n_candidates, n + 1 + (runner_up(&e, all.candidate, idx, n, walk_best(&e, &all, n)) >= 0));
    cr_expect(all.candidate[1].k == 15 && all.candidate[1].bytes < all.candidate[0].bytes &&
                  all.candidate[1].lab <= e.max_error,
              "here k 15 (every view) meets 0.8 with fewer bytes than k 9");
    expect_pruned_like(src, e, &all, out); /* so k 3 and 1 are not measured */
    b.max_bytes = 100;
    cr_expect_eq(btf_budget_compress(src, NULL, NULL, &b, out, &res, &err), BTF_ERR_RANGE);
    cr_expect(strstr(err.msg, "cannot hold"), "%s", err.msg);
    cr_expect_eq(btf_fs_size(out), -1, "a directory is not a file");
    btf_package *p = NULL;
    cr_expect_eq(btf_package_read(out, 0, &p, &err), BTF_OK, "the refused budget touched the earlier package: %s",
                 err.msg);
    btf_package_free(p);
    btf_free(src);
    fx_rmtree(dir);
}

/* The best candidate is tried once more with row centring, unless the caller chose a
 * centring; the choice is the lower error either way, and the package says how it
 * was made (its manifest's "center" and the budget record). */
Test(budget, the_best_candidate_is_retried_with_row_centring)
{
    char dir[64], out[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/p", dir);
    btf *src = material();
    btf_budget b = {0};
    b.max_bytes = 60000, b.k[0] = 1, b.k[1] = 3, b.n_k = 2;
    btf_budget_result res;
    btf_error err = {0};
    cr_assert_eq(btf_budget_compress(src, walk_only(), NULL, &b, out, &res, &err), BTF_OK, "%s", err.msg);
    const btf_budget_choice *c = res.candidate, *best = c[0].lab <= c[1].lab ? &c[0] : &c[1];
    const btf_budget_choice *other = best == &c[0] ? &c[1] : &c[0];
    cr_assert_eq(res.n_candidates, other->lab <= 1.03 * best->lab ? 4 : 3, "a close runner-up is retried too");
    cr_expect_eq(c[0].center, BTF_CENTER_DEFAULT);
    cr_expect_eq(c[1].center, BTF_CENTER_DEFAULT);
    cr_expect_eq(c[2].center, BTF_CENTER_ROW);
    cr_expect_eq(c[2].k, best->k, "the retry is the best uncentred candidate's k");
    const btf_budget_choice *win = c[2].n_chunks > 0 && c[2].lab < best->lab ? &c[2] : best;
    cr_expect_eq(res.center, win->center);
    cr_expect_eq(res.k, win->k);
    btf_package *p = NULL;
    cr_assert_eq(btf_package_read(out, 0, &p, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(p->center, win->center == BTF_CENTER_ROW ? BTF_CENTER_ROW : BTF_CENTER_NONE, "package center %d",
                 (int)p->center);
    cr_expect(p->budget && strstr(p->budget, "\"center\":\"row\""), "the record lists the centred candidate: %s",
              p->budget ? p->budget : "none");
    btf_package_free(p);
    btf_pca_options po = *walk_only(); /* a centring of the caller's: no retry */
    po.center = BTF_CENTER_NONE;
    cr_assert_eq(btf_budget_compress(src, &po, NULL, &b, out, &res, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(res.n_candidates, 2);
    cr_expect_eq(res.center, BTF_CENTER_NONE);
    btf_free(src);
    fx_rmtree(dir);
}

/* Besides the best, a candidate of another k that came within 3% of it (error under
 * a byte budget, bytes under an error target) is retried centred too, and no other
 * is: checked on the record of searches over k 1 and 3 at several budgets, at least
 * one of which has such a runner-up. */
Test(budget, a_close_runner_up_is_retried_with_row_centring_too)
{
    char dir[64], out[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/p", dir);
    btf *src = material();
    static const long long budgets[] = {20000, 30000, 40000};
    int close = 0;
    for (size_t n = 0; n < sizeof budgets / sizeof budgets[0]; n++) {
        btf_budget b = {0};
        b.max_bytes = budgets[n], b.k[0] = 1, b.k[1] = 3, b.n_k = 2;
        btf_budget_result res;
        btf_error err = {0};
        cr_assert_eq(btf_budget_compress(src, walk_only(), NULL, &b, out, &res, &err), BTF_OK, "%s", err.msg);
        const btf_budget_choice *c = res.candidate;
        int best = c[0].lab <= c[1].lab ? 0 : 1, other = 1 - best;
        int near = c[other].n_chunks > 0 && c[other].lab <= 1.03 * c[best].lab;
        cr_log_info("budget %lld: k %d Lab %.4f, k %d Lab %.4f: %d candidates", budgets[n], c[best].k, c[best].lab,
                    c[other].k, c[other].lab, res.n_candidates);
        cr_assert_eq(res.n_candidates, 3 + near, "budget %lld: %d candidates", budgets[n], res.n_candidates);
        cr_expect(c[2].center == BTF_CENTER_ROW && c[2].k == c[best].k, "the best's k centred first");
        if (near)
            cr_expect(c[3].center == BTF_CENTER_ROW && c[3].k == c[other].k, "then the runner-up's");
        close += near;
    }
    cr_assert_geq(close, 1, "no budget has a close runner-up: the test no longer covers it");
    btf_free(src);
    fx_rmtree(dir);
}

/* A budget that holds every component of the best candidate tries it again with
 * 1.5x the components (the renderer's limit and the blocks permitting), keeps the
 * larger one only when it wins, and grows nothing when the caller fixes the count. */
Test(budget, a_candidate_keeping_every_component_is_tried_with_more)
{
    char dir[64], out[128], ref[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/p", dir);
    snprintf(ref, sizeof ref, "%s/ref", dir);
    btf *src = material();
    btf_budget b = {0};
    b.max_bytes = 50000000, b.k[0] = 3, b.n_k = 1; /* holds any package of this material */
    btf_package_options opt = {0};
    opt.bits = 16; /* fine steps: every further component lowers the error (8 bits stop at about 8) */
    btf_budget_result res;
    btf_error err = {0};
    cr_assert_eq(btf_budget_compress(src, NULL, &opt, &b, out, &res, &err), BTF_OK, "%s", err.msg);
    cr_assert_geq(res.n_candidates, 3, "k 3, its centred retry, then the best with more components");
    const btf_budget_choice *c = res.candidate, *best = c[0].lab <= c[1].lab ? &c[0] : &c[1];
    cr_expect_eq(c[0].components, BTF_BUDGET_COMPONENTS);
    cr_expect_eq(best->n_chunks, best->components, "the budget holds every chunk of the first two");
    cr_expect_eq(c[2].components, BTF_BUDGET_COMPONENTS * 3 / 2, "components %d", c[2].components);
    cr_expect_eq(c[2].k, best->k);
    cr_expect_eq(c[2].center, best->center, "the grown candidate keeps the best one's centring");
    for (int i = 0; i < res.n_candidates; i++)
        if (c[i].n_chunks > 0)
            cr_expect_geq(c[i].lab + 1e-12, res.lab, "candidate %d beats the choice", i);
    /* the choice's error, recomputed by an independent compression with its settings */
    btf_pca_options po = {0};
    po.k = res.k, po.components = res.components, po.center = res.center == BTF_CENTER_ROW ? BTF_CENTER_ROW
                                                                                         : BTF_CENTER_NONE;
    cr_assert_eq(btf_package_compress(src, &po, &opt, ref, NULL, &err), BTF_OK, "%s", err.msg);
    btf_package *p = NULL;
    cr_assert_eq(btf_package_read(ref, 1, &p, &err), BTF_OK, "%s", err.msg);
    cr_assert_leq(res.n_chunks, p->n_chunks);
    cr_expect_float_eq(p->chunk[res.n_chunks - 1].lab, res.lab, 1e-9, "reference %.6f, chosen %.6f",
                       p->chunk[res.n_chunks - 1].lab, res.lab);
    btf_package_free(p);
    b.max_components = BTF_BUDGET_COMPONENTS; /* fixed by the caller: no growth */
    cr_assert_eq(btf_budget_compress(src, NULL, &opt, &b, out, &res, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(res.n_candidates, 2, "k 3 and its centred retry only");
    btf_free(src);
    fx_rmtree(dir);
}

/* Where the last power of 3 below the view count leaves more than two blocks, the
 * walk also tries two blocks (half the views, rounded up) before every view: on 21
 * views (9 leaves three blocks) the default ks are 9, 11, 21, 5, 3, 1, and the walk over
 * them measures what the full search predicts. */
Test(budget, two_blocks_are_tried_between_three_and_one)
{
    static const btf_ring r[3] = {{0.0f, 1, 0.0f}, {30.0f, 8, 0.0f}, {60.0f, 12, 0.0f}};
    char dir[64], out[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/p", dir);
    btf *src = fx_material(BTF_GEN_TILES, 16, r, 3);
    cr_assert_eq(src->views.n_dirs, 21);
    btf_budget e = {0};
    e.max_error = 0.8, e.full_search = 1;
    btf_budget_result all;
    btf_error err = {0};
    cr_assert_eq(btf_budget_compress(src, walk_only(), NULL, &e, out, &all, &err), BTF_OK, "%s", err.msg);
    static const int order[6] = {9, 11, 21, 5, 3, 1};
    int idx[BTF_BUDGET_MAX_CANDIDATES];
    expect_ks(&all, order, 6, idx); /* the full search's ks in order, each maybe followed by its growth */
    expect_pruned_like(src, e, &all, out);
    btf_free(src);
    fx_rmtree(dir);
}

/* Under an error target, the best candidate so far that kept every component and
 * missed the target by at most 15%, overtaken by one that meets it, is measured once
 * more with 1.5x the components before the walk goes on (btf__budget_overtaken): at
 * its count it never had the chance to meet the target. Here k 3 (first) misses by
 * about 9% and k 1 meets it; the grown k 3 follows k 1. */
Test(budget, a_best_overtaken_by_meeting_the_target_is_tried_with_more)
{
    char dir[64], out[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/p", dir);
    btf *src = material();
    btf_error err = {0};
    btf_package_options opt = {0};
    opt.bits = 16; /* fine steps: every further component lowers the error */
    double full[2]; /* k 3 and k 1 with all 16 components: their errors */
    for (int i = 0; i < 2; i++) {
        btf_budget a = {0};
        btf_budget_result ra;
        a.max_bytes = 50000000, a.k[0] = i == 0 ? 3 : 1, a.n_k = 1, a.max_components = BTF_BUDGET_COMPONENTS;
        cr_assert_eq(btf_budget_compress(src, NULL, &opt, &a, out, &ra, &err), BTF_OK, "%s", err.msg);
        cr_assert_eq(ra.candidate[0].n_chunks, BTF_BUDGET_COMPONENTS, "k %d: %d chunks kept", a.k[0],
                     ra.candidate[0].n_chunks);
        full[i] = ra.candidate[0].lab;
    }
    cr_log_info("k 3: CIELab %.4f, k 1: %.4f with every chunk", full[0], full[1]);
    double t = full[0] / 1.09;
    cr_assert_lt(full[1], t, "k 1 meets what k 3 misses by 9%%: the test's premise");
    btf_budget b = {0};
    btf_budget_result res;
    b.max_error = t, b.k[0] = 3, b.k[1] = 1, b.n_k = 2;
    cr_assert_eq(btf_budget_compress(src, NULL, &opt, &b, out, &res, &err), BTF_OK, "%s", err.msg);
    const btf_budget_choice *c = res.candidate;
    cr_assert_geq(res.n_candidates, 3);
    cr_expect(c[0].k == 3 && c[0].components == BTF_BUDGET_COMPONENTS && c[0].lab > t, "k 3 misses");
    cr_expect(c[1].k == 1 && c[1].lab <= t, "k 1 meets");
    cr_expect(c[2].k == 3 && c[2].components == BTF_BUDGET_COMPONENTS * 3 / 2 && c[2].center == c[0].center,
              "then k 3 with %d components, got k %d with %d", BTF_BUDGET_COMPONENTS * 3 / 2, c[2].k, c[2].components);
    cr_expect_leq(res.lab, t, "the choice meets the target");
    btf_free(src);
    fx_rmtree(dir);
}

/* A smaller k that wins keeping every component it has is grown (1.5x the
 * components) while the grown one wins and keeps them all, before the walk goes on
 * to the next smaller k: at the thesis format's bytes the generated tiles 3621 at
 * 64x64 went from k 3 with 16 components (CIELab 1.146) to k 5 with 36 (1.003), whose
 * 16 had lost to k 3 (doc/performance.md section 3). Here, ks 15, 3, 1 under 50,000
 * bytes with the rate-distortion steps: k 3 wins with all 16 kept and is grown to 24
 * before k 1 is measured. */
Test(budget, a_smaller_k_that_wins_keeping_every_component_is_grown_before_the_next)
{
    char dir[64], out[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/p", dir);
    btf *src = material();
    btf_budget b = {0};
    b.max_bytes = 50000;
    b.k[0] = 15, b.k[1] = 3, b.k[2] = 1, b.n_k = 3;
    btf_package_options ko = {0};
    ko.rd = 1;
    btf_budget_result res;
    btf_error err = {0};
    cr_assert_eq(btf_budget_compress(src, NULL, &ko, &b, out, &res, &err), BTF_OK, "%s", err.msg);
    const btf_budget_choice *c = res.candidate;
    for (int i = 0; i < res.n_candidates; i++)
        log_candidate(&res, i);
    cr_assert(c[1].k == 3 && c[1].components == 16 && c[1].n_chunks == 16 && beats(&b, &c[1], &c[0]),
              "k 3 wins over k 15 keeping all 16 components: the case this test needs");
    cr_expect(c[2].k == 3 && c[2].components == 24, "k 3 grown to 24 before k 1: k %d, %d", c[2].k, c[2].components);
    int i = 2, best = 1;
    for (; i < res.n_candidates && c[i].k == 3; i++) { /* each growth follows a winner that kept all */
        cr_expect(c[i - 1].n_chunks == c[i - 1].components && best == i - 1, "candidate %d grown from a winner", i);
        best = grown_beats(&b, &c[i], &c[i - 1], &c[best]) ? i : best;
    }
    cr_expect(i < res.n_candidates && c[i].k == 1, "then k 1");
    btf_free(src);
    fx_rmtree(dir);
}

/* Where the source has clipped samples (the tiles' highlights at 1) and the PCA fits
 * them, under a byte budget the best keeping n chunks of C > n components is measured
 * again with n components, and again while that wins by 1%; with --clipped keep, or
 * under an error target, it is not. */
Test(budget, a_best_keeping_fewer_chunks_is_measured_at_that_count_where_samples_are_clipped)
{
    char dir[64], out[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/p", dir);
    btf *src = material();
    double share = btf_pca_clipped_share(src);
    cr_assert_geq(share, BTF_PCA_CLIPPED_MIN_SHARE, "the tiles have clipped highlights (%g)", share);
    btf_budget b = {0};
    b.max_bytes = 30000, b.k[0] = 3, b.n_k = 1;
    btf_pca_options po = {0};
    po.center = BTF_CENTER_NONE; /* no centred retry: the walk is one candidate */
    btf_budget_result res;
    btf_error err = {0};
    cr_assert_eq(btf_budget_compress(src, &po, NULL, &b, out, &res, &err), BTF_OK, "%s", err.msg);
    for (int i = 0; i < res.n_candidates; i++)
        log_candidate(&res, i);
    const btf_budget_choice *c = res.candidate;
    cr_assert_lt(c[0].n_chunks, c[0].components, "this budget keeps fewer chunks than the 16 components");
    cr_assert_geq(res.n_candidates, 2, "the best measured again at its count");
    int best = 0;
    for (int i = 1; i < res.n_candidates; i++) {
        cr_expect_eq(c[i].components, c[best].n_chunks, "candidate %d: the best's count %d, got %d", i,
                     c[best].n_chunks, c[i].components);
        cr_expect(c[i].k == 3 && c[i].center == c[0].center && c[i].rd_fit == c[0].rd_fit, "candidate %d", i);
        int won = c[i].n_chunks > 0 && c[i].lab < 0.99 * c[best].lab;
        if (i + 1 < res.n_candidates)
            cr_expect(won && c[i].n_chunks < c[i].components, "a shrink after candidate %d, which did not win", i);
        best = won ? i : best;
    }
    cr_expect_eq(res.components, c[best].components);
    cr_expect_float_eq(res.lab, c[best].lab, 1e-12);
    po.clipped = BTF_CLIPPED_KEEP;
    cr_assert_eq(btf_budget_compress(src, &po, NULL, &b, out, &res, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(res.n_candidates, 1, "fitted as stored: the walk's one candidate only");
    po.clipped = BTF_CLIPPED_FIT;
    btf_budget e = {0};
    e.max_error = 1.0, e.k[0] = 3, e.n_k = 1;
    cr_assert_eq(btf_budget_compress(src, &po, NULL, &e, out, &res, &err), BTF_OK, "%s", err.msg);
    for (int i = 0; i < res.n_candidates; i++)
        cr_expect_eq(res.candidate[i].components, 16, "under an error target no shrink (candidate %d)", i);
    btf_free(src);
    fx_rmtree(dir);
}

/* The tiles as a rank-4 model of them stored as bytes (clamped to 0..1): what a
 * published low-rank reconstruction is. */
static btf *rank4_bytes(void)
{
    btf *t = material(), *out = NULL;
    btf_pca_options po = {0};
    po.k = 3, po.components = 4, po.rounding = BTF_ROUNDING_KEEP;
    btf_pca_model *m = NULL;
    btf_error err = {0};
    cr_assert_eq(btf_pca_compress(t, &po, NULL, NULL, &m, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_create(t->width, t->height, &t->lights, &t->views, BTF_F32, &out, &err), BTF_OK, "%s", err.msg);
    for (int v = 0; v < t->views.n_dirs; v++)
        for (int l = 0; l < t->lights.n_dirs; l++)
            for (int y = 0; y < t->height; y++)
                for (int x = 0; x < t->width; x++)
                    for (int c = 0; c < 3; c++) {
                        float s = btf_pca_model_value(m, v, l, x, y, c, 4);
                        s = s < 0.0f ? 0.0f : s > 1.0f ? 1.0f : s;
                        ((float *)out->data)[btf_index(out, v, l, x, y, c)] = roundf(s * 255.0f) / 255.0f;
                    }
    btf_pca_model_free(m), btf_free(t);
    return out;
}

/* A candidate whose blocks hold fewer components than it was given (the rest fit only
 * the source's rounding: btf_pca_options.rounding) keeps no more chunks than they hold,
 * is not grown although a budget that holds everything keeps every chunk it has, and is
 * not compressed again at its count; with every component kept the search grows it. */
Test(budget, a_candidate_cut_at_the_source_rounding_is_neither_grown_nor_shrunk)
{
    char dir[64], out[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/p", dir);
    btf *src = rank4_bytes();
    btf_budget b = {0};
    b.max_bytes = 50000000, b.k[0] = 3, b.n_k = 1; /* holds any package of this material */
    btf_package_options opt = {0};
    opt.rd = 1; /* the CLI's default: the search reads each candidate's model */
    btf_budget_result res;
    btf_error err = {0};
    cr_assert_eq(btf_budget_compress(src, NULL, &opt, &b, out, &res, &err), BTF_OK, "%s", err.msg);
    for (int i = 0; i < res.n_candidates; i++) {
        const btf_budget_choice *c = &res.candidate[i];
        log_candidate(&res, i);
        /* uncentred the 4 terms; centred the mean and 4 more */
        cr_expect_leq(c->n_chunks, c->center == BTF_CENTER_ROW ? 5 : 4, "candidate %d keeps %d chunks", i,
                      c->n_chunks);
        cr_expect_eq(c->components, BTF_BUDGET_COMPONENTS, "candidate %d: %d components (grown or shrunk)", i,
                     c->components);
    }
    cr_expect_eq(res.n_candidates, 2, "k 3 and its centred retry only");
    btf_pca_options keep = {0};
    keep.rounding = BTF_ROUNDING_KEEP;
    cr_assert_eq(btf_budget_compress(src, &keep, &opt, &b, out, &res, &err), BTF_OK, "%s", err.msg);
    int grown = 0;
    for (int i = 0; i < res.n_candidates; i++)
        grown |= res.candidate[i].components > BTF_BUDGET_COMPONENTS;
    cr_expect(grown, "with every component kept, a candidate keeping all 16 chunks is grown");
    btf_free(src);
    fx_rmtree(dir);
}

/* Under a byte budget a larger k that loses keeping every component it has is
 * measured again with 1.5x as many only when its error times 0.7 (below the most one
 * such step gained in the searches measured, 0.74) is below the best's: one further
 * behind cannot catch up. Generated stone and knit at 16x16 under 57 views: k 27
 * loses to k 9 within reach, and k 57 (one basis for every view) falls far behind
 * k 1. In each walk, a larger k that lost with every
 * chunk kept is followed by its growth exactly when it was within that reach. */
Test(budget, a_larger_k_far_behind_under_a_byte_budget_is_not_grown)
{
    char dir[64], out[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/p", dir);
    static const btf_ring r[5] = {{0.0f, 1, 0.0f}, {20.0f, 8, 0.0f}, {40.0f, 12, 0.0f}, {60.0f, 16, 0.0f}, {75.0f, 20, 0.0f}};
    static const btf_pca_options keep = {.clipped = BTF_CLIPPED_KEEP, .rounding = BTF_ROUNDING_KEEP};
    int far = 0, near = 0;
    for (int t = 0; t < 3; t++) {
        btf *src = fx_material(t == 1 ? BTF_GEN_KNIT : BTF_GEN_STONE, 16, r, 5);
        cr_assert_eq(src->views.n_dirs, 57);
        btf_budget b = {0};
        b.max_bytes = 1000000;
        b.k[0] = t < 2 ? 9 : 1, b.k[1] = t < 2 ? 27 : 57, b.n_k = 2; /* k 57: one basis for every view */
        btf_error err = {0};
        btf_budget_result res;
        cr_assert_eq(btf_budget_compress(src, &keep, NULL, &b, out, &res, &err), BTF_OK, "%s", err.msg);
        const btf_budget_choice *c = res.candidate;
        for (int i = 0; i < res.n_candidates; i++)
            log_candidate(&res, i);
        for (int i = 1; i < res.n_candidates && c[i].center != BTF_CENTER_ROW; i++) { /* the walk's candidates */
            if (c[i].k == c[i - 1].k)
                continue; /* a growth */
            int best = walk_best(&b, &res, i); /* before candidate i */
            int lost = walk_best(&b, &res, i + 1) != i, kept = c[i].n_chunks == c[i].components;
            if (c[i].k > c[0].k && lost && kept) {
                int in_reach = c[i].lab * 0.7 < c[best].lab;
                int grown = i + 1 < res.n_candidates && c[i + 1].k == c[i].k && c[i + 1].components > c[i].components;
                cr_expect_eq(grown, in_reach, "material %d: k %d at CIELab %.4f against the best's %.4f: grown %d", t,
                             c[i].k, c[i].lab, c[best].lab, grown);
                far += !in_reach, near += in_reach;
            }
        }
        btf_free(src);
    }
    cr_log_info("larger ks that lost keeping every component: %d far behind, %d within reach", far, near);
    cr_expect_gt(far, 0, "k 57 is far behind k 1");
    cr_expect_gt(near, 0, "the default walks leave larger ks within reach");
    fx_rmtree(dir);
}

/* Under an error target the walk does not measure a larger k whose blocks are unions
 * of the best's (consecutive views, a multiple of its k) when that best keeps every
 * component it has and misses the target by more than 15%: each larger block's PCA fits
 * each of the best's blocks no better with as many components, so it would miss by
 * more and be neither chosen nor grown. The premise checked on a search of k 9 and 27
 * alone: k 27 has the larger error. */
Test(budget, a_larger_k_is_not_measured_when_the_best_misses_far)
{
    char dir[64], out[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/p", dir);
    static const btf_ring r[4] = {{0.0f, 1, 0.0f}, {25.0f, 8, 0.0f}, {50.0f, 15, 0.0f}, {70.0f, 30, 0.0f}};
    btf *src = fx_material(BTF_GEN_KNIT, 16, r, 4); /* the default ks: 9, 27, 54, 5, 3, 1 */
    static const btf_pca_options keep = {.clipped = BTF_CLIPPED_KEEP, .rounding = BTF_ROUNDING_KEEP};
    cr_assert_eq(src->views.n_dirs, 54);
    btf_budget e = {0};
    e.max_error = 0.3, e.k[0] = 9, e.k[1] = 27, e.n_k = 2, e.max_components = BTF_BUDGET_COMPONENTS;
    btf_budget_result all, res;
    btf_error err = {0};
    cr_assert_eq(btf_budget_compress(src, &keep, NULL, &e, out, &all, &err), BTF_OK, "%s", err.msg);
    const btf_budget_choice *k9 = NULL, *k27 = NULL;
    for (int i = 0; i < all.n_candidates; i++) {
        log_candidate(&all, i);
        const btf_budget_choice *c = &all.candidate[i];
        if (c->center != BTF_CENTER_ROW && c->components == BTF_BUDGET_COMPONENTS)
            k9 = c->k == 9 && !k9 ? c : k9, k27 = c->k == 27 && !k27 ? c : k27;
    }
    cr_assert(k9 && k27, "the search measures k 9 and 27");
    cr_assert_eq(k9->n_chunks, k9->components, "k 9 keeps every component");
    cr_assert_gt(k9->lab, 1.15 * e.max_error, "k 9 misses 0.4 by more than 15%%: CIELab %.4f", k9->lab);
    cr_expect_gt(k27->lab, k9->lab, "k 27 fits worse: CIELab %.4f against %.4f", k27->lab, k9->lab);
    e.n_k = 0, e.max_components = 0; /* the default walk */
    cr_assert_eq(btf_budget_compress(src, &keep, NULL, &e, out, &res, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(res.candidate[0].k, 9);
    for (int i = 0; i < res.n_candidates; i++) {
        log_candidate(&res, i);
        cr_expect_leq(res.candidate[i].k, 9, "candidate %d: k %d measured", i, res.candidate[i].k);
    }
    cr_expect(res.met, "a smaller k meets 0.4: CIELab %.4f", res.lab);
    btf_free(src);
    fx_rmtree(dir);
}

/* Under an error target a candidate after the first that misses it keeping every
 * component, in fewer bytes than the best takes, is grown while each growth still does,
 * lowers the error by 1% and may meet the target under the best's bytes (the steps it
 * needs at 0.88x the error and 1.45x the bytes a step, then at its last step's ratios),
 * until one takes the best's place. Knit at 128x128 under 27 views, CIELab 1.6: k 9
 * meets it with its 16 components; k 27 (one block: a third of the textures) misses it
 * by 23% (beyond the 15% within which a larger k that lost is grown once) in 0.43x the
 * bytes, and grown twice meets it in fewer bytes than k 9. */
Test(budget, a_cheaper_candidate_missing_the_error_target_is_grown)
{
    char dir[64], out[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/p", dir);
    static const btf_pca_options keep = {.clipped = BTF_CLIPPED_KEEP, .rounding = BTF_ROUNDING_KEEP};
    static const btf_ring r[3] = {{0.0f, 1, 0.0f}, {30.0f, 8, 0.0f}, {60.0f, 18, 0.0f}};
    btf *src = fx_material(BTF_GEN_KNIT, 128, r, 3);
    btf_budget e = {0};
    e.max_error = 1.6, e.k[0] = 9, e.k[1] = 27, e.n_k = 2;
    btf_budget_result res;
    btf_error err = {0};
    cr_assert_eq(btf_budget_compress(src, &keep, NULL, &e, out, &res, &err), BTF_OK, "%s", err.msg);
    const btf_budget_choice *c = res.candidate;
    for (int i = 0; i < res.n_candidates; i++)
        log_candidate(&res, i);
    int grown = 0;
    double rl = 0.88, rb = 1.45;
    for (int i = 1; i < res.n_candidates && c[i].center != BTF_CENTER_ROW; i++) {
        int growth = c[i].k == c[i - 1].k && c[i].components > c[i - 1].components;
        int best = walk_best(&e, &res, i); /* before candidate i */
        if (walk_best(&e, &res, i + 1) == i)
            continue; /* it took the best's place */
        if (growth && c[i].lab > 0.99 * c[i - 1].lab)
            continue; /* more components did not help: the growth ends */
        if (growth)
            rl = c[i].lab / c[i - 1].lab, rb = (double)c[i].bytes / (double)c[i - 1].bytes;
        double m = ceil(log(e.max_error / c[i].lab) / log(rl));
        int worth = c[i].n_chunks == c[i].components && c[i].lab > e.max_error && c[i].bytes < c[best].bytes &&
                    (double)c[i].bytes * pow(rb, m > 1.0 ? m : 1.0) < (double)c[best].bytes;
        int next_grown = i + 1 < res.n_candidates && c[i + 1].k == c[i].k && c[i + 1].components > c[i].components &&
                         c[i + 1].center == c[i].center;
        cr_expect_eq(next_grown, worth && c[i].components < BTF_BUDGET_MAX_COMPONENTS,
                     "candidate %d (k %d, %d components, CIELab %.4f, %lld bytes; the best %lld): grown %d", i, c[i].k,
                     c[i].components, c[i].lab, c[i].bytes, c[best].bytes, next_grown);
        grown += next_grown;
    }
    cr_expect_gt(grown, 0, "k 27 misses the target in fewer bytes than k 9 and is grown");
    cr_expect(res.met && res.k == 27 && res.bytes < c[0].bytes, "k 27 grown meets CIELab %.2f in fewer bytes than k 9: "
              "k %d, %lld bytes against %lld", e.max_error, res.k, res.bytes, c[0].bytes);
    btf_free(src);
    fx_rmtree(dir);
}
