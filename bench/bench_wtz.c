/* bench_wtz.c - what the weights codings save (doc/package-format.md sections 5.4 and
 * 5.5, performance numbers in section 11.2): per material `btf compress` (its
 * defaults, no thumbnail; then under `--max-error` at the thesis format's error),
 * every 16-bit weights file of the package decoded and coded again as wt-JJ.z and as
 * wt-JJ.pz, at the same quantised weights (so at the package's own error): the
 * weights' bytes as written (the smallest of wt-JJ.z, wt-JJ.pz and wt-JJ.webp per
 * component), as wt-JJ.z alone (the writers before wt-JJ.pz) and as the smaller of
 * wt-JJ.z and wt-JJ.pz (the writers before wt-JJ.webp), and the package's bytes each
 * way. The rate-distortion choice also sees the smaller rates, so a package
 * compressed by an earlier writer differs by a little more than these lines (its
 * steps).
 *
 *   wtz_MAT_package_bytes       chunk files + manifest as written
 *   wtz_MAT_weights_bytes       its 16-bit weights files
 *   wtz_MAT_weights_z_bytes     the same weights as wt-JJ.z
 *   wtz_MAT_weights_zpz_bytes   the same as the smaller of wt-JJ.z and wt-JJ.pz
 *   wtz_MAT_weights_ratio       written / wt-JJ.z alone
 *   wtz_MAT_weights_webp_ratio  written / the smaller of wt-JJ.z and wt-JJ.pz
 *   wtz_MAT_package_ratio       written / with wt-JJ.z alone
 *   wtz_MAT_package_webp_ratio  written / with the smaller of wt-JJ.z and wt-JJ.pz
 *   wtz_MAT_pz_components       components written as wt-JJ.pz
 *   wtz_MAT_webp_components     components written as wt-JJ.webp
 *
 * Generated materials at seeds no test uses (64x64, tiles at 128x128); about 4 minutes
 * on 2 cores. Needs `make build` ($BUILD/btf, BUILD default build). */
#include "bench_util.h"
#include "btf.h"
#include "btf_fs.h"
#include "btf_manifest.h"
#include "btf_package.h"
#include "btf_wtz.h"
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* One material to compress: a name, the `btf compress` source and its extra flags. */
typedef struct bench_case {
    const char *name, *src, *flags;
} bench_case;

static const bench_case cases[] = {
    {"tiles64", "gen:tiles:64:4711", ""},
    {"knit64", "gen:knit:64:4712", ""},
    {"stone64", "gen:stone:64:4713", ""},
    {"tiles128", "gen:tiles:128:4714", ""},
    /* under a budget at the thesis format's error (doc/performance.md section 11) */
    {"tiles64_budget", "gen:tiles:64:4711", "--max-error 2.2555"},
    {"knit64_budget", "gen:knit:64:4712", "--max-error 2.4768"},
};

/* What recode adds up over a package's weights files. */
typedef struct wtz_sums {
    long long z, pz, zpz, as; /* as wt-JJ.z, as wt-JJ.pz, the smaller of those two, as written */
    int kinds[3];             /* files written in each coding (BTF_WTZ_*) */
} wtz_sums;

/* File f of the package in dir: its 16-bit weights recoded into *s; 1 when f is a
 * version-3 weights file (wt-JJ.z, .pz or .webp), 0 when not, -1 on error. */
static int recode(const btf_package *p, const char *dir, const char *f, const int *prev, wtz_sums *s)
{
    int kind = btf_wtz_kind_of(f);
    if (kind < 0)
        return 0;
    int V = p->views.n_dirs, L = p->lights.n_dirs;
    size_t n = (size_t)V * L * 3, nd = 0, n1 = 0, n2 = 0;
    char path[8300], *raw = NULL;
    uint8_t *e1 = NULL, *e2 = NULL;
    uint16_t *q = malloc(n * sizeof *q);
    btf_error err = {{0}};
    snprintf(path, sizeof path, "%s/%s", dir, f);
    int ok = q && btf_fs_read(path, btf_wtz_max_bytes(V, L), &raw, &nd, &err) == BTF_OK &&
             btf_wtz_decode_kind(kind, (const uint8_t *)raw, nd, V, L, prev, q, path, &err) == BTF_OK &&
             btf_wtz_encode(q, V, L, &e1, &n1, &err) == BTF_OK &&
             btf_wtz_encode_pred(q, V, L, prev, &e2, &n2, &err) == BTF_OK;
    if (!ok)
        fprintf(stderr, "bench_wtz: %s\n", err.msg);
    s->z += (long long)n1, s->pz += (long long)n2, s->zpz += (long long)(n1 < n2 ? n1 : n2), s->as += (long long)nd;
    s->kinds[kind]++;
    free(q), free(raw), free(e1), free(e2);
    return ok ? 1 : -1;
}

static int run_case(const bench_case *c, const char *btf, const char *tmp)
{
    char dir[600], cmd[2000];
    snprintf(dir, sizeof dir, "%s/%s", tmp, c->name);
    snprintf(cmd, sizeof cmd, "'%s' compress '%s' '%s' --no-thumbnail --quiet %s", btf, c->src, dir, c->flags);
    fprintf(stderr, "bench_wtz: %s\n", cmd);
    btf_package p;
    memset(&p, 0, sizeof p);
    btf_error err = {{0}};
    if (system(cmd) != 0 || btf_manifest_load(dir, &p, &err) != BTF_OK) {
        fprintf(stderr, "bench_wtz: %s: %s\n", c->name, err.msg[0] ? err.msg : "compress failed");
        btf_manifest_clear(&p);
        return -1;
    }
    int *prev = malloc((size_t)p.views.n_dirs * sizeof *prev), bad = !prev;
    wtz_sums s = {0};
    long long pkg = 0;
    if (prev)
        btf_wtz_prev_views(p.blocks->block_of_view, p.views.n_dirs, prev);
    for (int i = 0; !bad && i < p.n_chunks; i++) {
        pkg += p.chunk[i].bytes;
        for (int k = 0; !bad && k < p.chunk[i].n_files; k++)
            bad = recode(&p, dir, p.chunk[i].files[k], prev, &s) < 0;
    }
    char mpath[700];
    snprintf(mpath, sizeof mpath, "%s/manifest.json", dir);
    pkg += btf_fs_size(mpath);
    if (!bad) {
        long long with_z = pkg - s.as + s.z, with_zpz = pkg - s.as + s.zpz;
        printf("wtz_%s_package_bytes %lld B\n", c->name, pkg);
        printf("wtz_%s_weights_bytes %lld B\n", c->name, s.as);
        printf("wtz_%s_weights_z_bytes %lld B\n", c->name, s.z);
        printf("wtz_%s_weights_zpz_bytes %lld B\n", c->name, s.zpz);
        printf("wtz_%s_weights_ratio %.4f x\n", c->name, (double)s.as / (double)s.z);
        printf("wtz_%s_weights_webp_ratio %.4f x\n", c->name, (double)s.as / (double)s.zpz);
        printf("wtz_%s_package_ratio %.4f x\n", c->name, (double)pkg / (double)with_z);
        printf("wtz_%s_package_webp_ratio %.4f x\n", c->name, (double)pkg / (double)with_zpz);
        printf("wtz_%s_pz_components %d count\n", c->name, s.kinds[BTF_WTZ_PZ]);
        printf("wtz_%s_webp_components %d count\n", c->name, s.kinds[BTF_WTZ_WEBP]);
        printf("# %s: weights %lld B as written (wt-JJ.z %d, .pz %d, .webp %d); as wt-JJ.z alone %lld B (%.3fx), as "
               "the smaller of .z and .pz %lld B (%.3fx); package %lld B against %lld B (%.3fx) and %lld B (%.3fx)\n",
               c->name, s.as, s.kinds[BTF_WTZ_Z], s.kinds[BTF_WTZ_PZ], s.kinds[BTF_WTZ_WEBP], s.z,
               (double)s.as / (double)s.z, s.zpz, (double)s.as / (double)s.zpz, pkg, with_z,
               (double)pkg / (double)with_z, with_zpz, (double)pkg / (double)with_zpz);
    }
    free(prev);
    btf_manifest_clear(&p);
    btf_fs_rmtree(dir, NULL);
    return bad ? -1 : 0;
}

int main(void)
{
    char btf[600], tmp[64];
    if (!bench_btf_and_tmp("wtz", btf, tmp))
        return 1;
    int bad = 0;
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++)
        bad |= run_case(&cases[i], btf, tmp) != 0;
    btf_fs_rmtree(tmp, NULL);
    return bad;
}
