/* btf_budget.h - compression to a byte budget or an error target: the settings
 * (views per block k, number of chunks) chosen by measuring, not guessed.
 *
 *     btf_budget b = {0};  b.max_bytes = 400000;          // or b.max_error = 1.0 (CIELab)
 *     btf_budget_result res;
 *     if (btf_budget_compress(src, NULL, NULL, &b, "lib/wool", &res, &err) == BTF_OK)
 *         printf("k %d, %d chunks, %lld bytes, Lab %.3f\n", res.k, res.n_chunks, res.bytes, res.lab);
 *
 * Each candidate k is compressed once with the largest component count (the
 * default ks walk from 9 up, 27, 81, ... each 3x the last, then two blocks where the
 * last leaves more (41 of 81 views), then every view, while
 * each beats the best, and when none above 9 won, down to 3 and 1 while each beats
 * it; full_search measures every one of them); its
 * manifest gives the bytes and the measured CIELab error of every chunk prefix
 * (the chunk order is by error drop per byte, doc/package-format.md section 10.3),
 * so every budget of that k is read off one compression. With opt->rd (version 3)
 * and max_bytes, each k's steps are fitted to the bytes
 * (the writer's inside channel, compress/btf_compress.h). Unless pca sets a centring, the best
 * candidate is then tried once more with the thesis's row centring (component 0 =
 * the texel's mean; on a window it must win by BTF_BUDGET_SCREEN_EDGE), which wins
 * on materials made of a mean and a few terms. When the best candidate keeps every component it
 * was compressed with (the component count, not the budget, stopped it; with
 * max_error, it also misses the target) and the caller did not fix the count, it is
 * tried again with half as many components again (16, 24, 36, 56, 64:
 * BTF_BUDGET_MAX_COMPONENTS) while that keeps more chunks at a lower error; in the
 * walk a larger k that loses that way is tried once so before it counts as lost.
 *
 * The candidates are measured on the material's centre window of half its width
 * and height when a side has BTF_BUDGET_SCREEN_MIN texels or more (texture bytes
 * counted whole texels / window texels times over; budget->full_search: on the
 * whole material), and with opt->rd only measured, nothing written
 * (an estimate: chunk bytes the allocation's estimates, errors
 * measured on the quantised model as ever). The best one is then compressed from
 * the whole material (with rd and no window, from its kept model and ladder; with a
 * window, its ladder measured near the steps the window chose, and a grown
 * candidate's near those it grew from: btf_package_channel.rd_near), its prefix
 * read off the files as written (fitted again once when the chunks its allocation
 * kept came out over the budget, each texture's rates scaled by its atlas as
 * written over its estimate), cut to the chosen prefix, and it replaces OUT like
 * btf_package_compress. With max_error and rd the winner's model is first compressed
 * again with its steps fitted to byte budgets (bisected for the fewest bytes whose
 * best prefix meets the target: btf__budget_fit_error), a trial that meets it taking
 * the winner's place. With max_error the written winner's chunk count is then
 * settled on its error over every texel and pair (btf_package_compare, what btf eval
 * reports; the manifest's per-chunk errors are a texel sample's): the fewest chunks
 * meeting the target that way, the result's lab that error. Its steps are the equal-noise ones of
 * opt->tex_noise: when no candidate meets the error with them, the whole search runs
 * again with half, then a quarter of the noise (finer steps; BTF_BUDGET_FINER rounds),
 * each into OUT.finer-PID, replacing OUT when it meets the error with fewer bytes (or
 * misses it by less); the record says which noise ("tex_noise"). What the search
 * costs and wins is measured by bench/bench_search.sh and bench/bench_rd.sh.
 */
#ifndef BTF_BUDGET_H
#define BTF_BUDGET_H

#include "btf_package.h"

#ifdef __cplusplus
extern "C" {
#endif

#define BTF_BUDGET_MAX_K 8 /* candidate k values at most */
#define BTF_BUDGET_COMPONENTS 16     /* components per candidate when the caller fixes none */
#define BTF_BUDGET_MAX_COMPONENTS 64 /* the most the growth tries: the renderer's chunk limit */
#define BTF_BUDGET_SCREEN_MIN 128 /* a side of at least this many texels is halved to screen */
/* On a window the centred retry replaces the best only with this much less error (or
 * fewer bytes): a small edge on the window can be a loss on the whole material,
 * and where centring pays it wins by much more. */
#define BTF_BUDGET_SCREEN_EDGE 0.03
#define BTF_BUDGET_FINER 2 /* max_error out of the default steps' reach: searches again at 1/2, 1/4 the noise */
#define BTF_BUDGET_MAX_GROW 4        /* growth rounds: 16 -> 24 -> 36 -> 56 -> 64 */
#define BTF_BUDGET_MAX_SHRINK 3      /* rounds of the best at the count it keeps (clipped samples) */
/* each k and its growth in the walk (a smaller k that wins: every round), the centred
 * retries (the best, a close runner-up), the growth and shrinking rounds */
#define BTF_BUDGET_MAX_CANDIDATES \
    (BTF_BUDGET_MAX_K * (1 + BTF_BUDGET_MAX_GROW) + 2 + BTF_BUDGET_MAX_GROW + BTF_BUDGET_MAX_SHRINK)

/* What to meet; plain value. Exactly one of max_bytes, max_error is set. */
typedef struct btf_budget {
    long long max_bytes; /* > 0: the least error within this many bytes (manifest + chunk files) */
    double max_error;    /* > 0: the fewest bytes whose CIELab error (as btf eval reports) is <= this */
    int max_components;  /* components compressed per candidate; 0 = 16, then 1.5x while all are kept */
    /* candidate k; n_k = 0: 9, 27, 81, ... (each 3x the last below the view count),
     * half the view count rounded up (where the last leaves more than two blocks),
     * the view count, 3 and 1, those the views allow, walked from 9 up, else down,
     * while each beats the best */
    int k[BTF_BUDGET_MAX_K], n_k;
    /* 1 = candidates measured on the whole material, not on its centre window (with
     * rd), and every default k measured */
    int full_search;
} btf_budget;

/* One candidate's best prefix; plain value. */
typedef struct btf_budget_choice {
    int k, n_chunks; /* n_chunks 0: no prefix of this k meets the budget */
    int components;  /* components compressed (the chunks available before the cut) */
    long long bytes;
    double lab, rmse;
    int rd_fit; /* with opt->rd and max_bytes: 1 = steps fitted to the bytes, 0 = the equal-noise error */
    btf_center center; /* the PCA's centring (BTF_CENTER_ROW: the centred retry) */
} btf_budget_choice;

/* What was chosen and what each candidate measured; plain value. */
typedef struct btf_budget_result {
    int k, n_chunks, rd_fit;
    int components; /* components the chosen candidate was compressed with */
    btf_center center;
    long long bytes;
    double lab, rmse;
    int met;         /* 1: the budget is met (0 with max_error: the lowest error reached is reported) */
    float tex_noise; /* with max_error: the texture noise of the steps that met it, or of the last try (the
                      * default steps did not reach it: halved up to BTF_BUDGET_FINER times); else 0 */
    int screen_width, screen_height; /* the window the candidates were measured on (with rd) */
    int refits; /* with rd and max_bytes: 1 when the winner was written a second time, its steps fitted to
                 * what the first write came out over or under the budget by (the better write is kept) */
    btf_budget_choice first; /* with refits: the first write's best prefix */
    int n_candidates;
    btf_budget_choice candidate[BTF_BUDGET_MAX_CANDIDATES];
} btf_budget_result;

/* Compresses src into the package OUT under the budget. pca and opt give the other
 * settings (k and components are the budget's to choose; NULL = defaults). */
btf_result btf_budget_compress(const btf *src, const btf_pca_options *pca, const btf_package_options *opt,
                               const btf_budget *budget, const char *out, btf_budget_result *res, btf_error *err);

#ifdef __cplusplus
}
#endif
#endif
