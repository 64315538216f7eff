/* cmd_import_thesis.c - `btf import-thesis DIR OUT [--size N] [--ext png|jpg] [--sampling S]`:
 * reconstructs the full BTF from one of the thesis's published packages
 * (btf_import_thesis) and writes it as a UBO2003-named image directory, or as a
 * DFMF08FC file when OUT ends in `.btf` (full rank).
 *
 *     btf import-thesis wool/ out/wool64 --size 64    # wool/: a thesis package (meta.json, j.png, R.png)
 *     btf import-thesis dome/ out/dome --sampling order.json   # its directions in their listed order
 */
#include "btf_args.h"
#include "btf_cli.h"
#include "btf_io.h"
#include "btf_source.h"
#include "btf_input.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void import_thesis_usage(FILE *f)
{
    fprintf(f, "usage: btf import-thesis DIR OUT [--size N] [--ext png|jpg] [--sampling S]\n"
               "\n"
               "Reconstructs the BTF stored in a thesis package DIR (meta.json, 0.png.., R.png),\n"
               "values clamped to 0..1 and stored as 8-bit, and writes it.\n"
               "  OUT          a directory of UBO2003-named images (one per light x view), or a\n"
               "               DFMF08FC file if OUT ends in .btf (full rank, float32)\n"
               "  --size N     N x N texels (default 256, the package's own size); sizes that\n"
               "               divide 256 are box-filtered, others area-weighted\n"
               "  --ext E      image format for a directory OUT: png (default) or jpg\n"
               "  --sampling S the package's directions in its own index order: ubo2003, dome151\n"
               "               or a JSON file (rings, or a direction list for packages whose\n"
               "               order is not canonical; doc/data-model.md). Default: UBO2003\n"
               "               for 81 directions, the dome for 151\n");
    btf_args_exit_codes(f);
}

/* Parsed command line; stack value of cmd_import_thesis, strings point into argv. */
typedef struct import_thesis_opts {
    const char *in, *out, *ext;
    const char *sampling; /* NULL: chosen from the direction count */
    int size;             /* 0 = the package's own */
} import_thesis_opts;

/* One option or positional of `btf import-thesis` (btf_args_fn). */
static int import_thesis_option(void *ctx, const btf_args *a, int c, const char *v)
{
    static const char *const exts[] = {"png", "jpg"};
    import_thesis_opts *o = ctx;
    int e = 0, rc = 0;
    switch (c) {
    case BTF_ARG_POS: *(a->npos ? &o->out : &o->in) = v; break;
    case 's': rc = btf_args_int(a, v, 1, 4096, &o->size); break;
    case 'e': rc = btf_args_enum(a, v, exts, 2, &e), o->ext = exts[e]; break;
    case 'S': o->sampling = v; break;
    }
    return rc;
}

/* 0 ok, 2 usage error (message printed), -1 help printed. */
static int import_thesis_parse(int argc, char **argv, import_thesis_opts *o)
{
    static const btf_args_spec spec = {"import-thesis", "size:s ext:e sampling:S", import_thesis_usage, 2};
    memset(o, 0, sizeof *o);
    o->ext = "png";
    return btf_args_parse(&spec, argc, argv, import_thesis_option, o);
}

static int import_thesis_ends_with(const char *s, const char *suffix)
{
    size_t n = strlen(s), m = strlen(suffix);
    return n >= m && strcmp(s + n - m, suffix) == 0;
}

/* Last path component of dir (without trailing slashes) into buf, as image name prefix. */
static void import_thesis_prefix(const char *dir, char *buf, size_t n)
{
    size_t len = strlen(dir);
    while (len > 1 && dir[len - 1] == '/')
        len--;
    size_t start = len;
    while (start > 0 && dir[start - 1] != '/')
        start--;
    size_t m = len - start < n - 1 ? len - start : n - 1;
    memcpy(buf, dir + start, m);
    buf[m] = '\0';
    if (!buf[0] || !strcmp(buf, ".") || !strcmp(buf, ".."))
        snprintf(buf, n, "thesis");
}

/* The command once its options are parsed; the exit code. */
static int import_thesis_main(void *opts)
{
    import_thesis_opts *a = opts;
    btf_load_options o = {0};
    o.width = o.height = a->size;
    btf *b = NULL;
    btf_error e = {0};
    btf_dirset set;
    btf_result r = a->sampling ? btf_source_sampling(a->sampling, &set, &e) : BTF_OK;
    o.sampling = a->sampling ? &set : NULL;
    if (r == BTF_OK)
        r = btf_import_thesis(a->in, &o, &b, &e);
    if (r == BTF_OK) {
        if (import_thesis_ends_with(a->out, ".btf")) {
            r = btf_save_dfmf(b, a->out, 0, &e);
        } else {
            char prefix[256];
            import_thesis_prefix(a->in, prefix, sizeof prefix);
            r = btf_save_ubo2003_dir(b, a->out, prefix, a->ext, &e);
        }
    }
    if (r == BTF_OK)
        printf("%s: %dx%d texels, %d lights x %d views -> %s\n", a->in, b->width, b->height, b->lights.n_dirs,
               b->views.n_dirs, a->out);
    btf_free(b);
    if (r != BTF_OK) {
        fprintf(stderr, "btf import-thesis: %s (%s)\n", e.msg, btf_result_string(r));
        return 1;
    }
    return 0;
}

int cmd_import_thesis(int argc, char **argv)
{
    import_thesis_opts a;
    return btf_args_finish(import_thesis_parse(argc, argv, &a), import_thesis_main, &a);
}
