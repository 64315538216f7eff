/* cmd_gen.c - `btf gen KIND OUT`: writes a synthetic material (bench/gen/btf_gen.h).
 *
 *     btf gen knit out/knit64 --size 64
 *     btf gen tiles tiles.btf --sampling dome151 --format btf
 *
 * Image formats write a UBO2003-named directory (one image per light x view),
 * rendered and written one view at a time (btf_gen_views_open, btf_views_save_ubo2003),
 * so a full-size material (dome151 at 400 x 400) needs one view in memory; `btf`
 * writes a DFMF `.btf` file (btf_save_dfmf, the material in memory), full rank
 * unless --components is given.
 * Samples are generated as 8-bit (what the images store).
 */
#include "btf_args.h"
#include "btf_cli.h"
#include "btf_gen.h"
#include "btf_io.h"
#include "btf_source.h"
#include "btf_output.h"
#include "btf_common.h"

#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Parsed command line; stack value of cmd_gen, strings point into argv. */
typedef struct gen_opts {
    int kind;
    const char *out, *sampling, *format;
    int size;
    unsigned seed;
    int components; /* DFMF factors per channel, 0 = full rank */
} gen_opts;

static void gen_usage(FILE *f)
{
    fprintf(f, "usage: btf gen KIND OUT [--size N] [--sampling ubo2003|dome151|FILE.json] [--seed S]\n"
               "                        [--format png|jpg|btf] [--components C]\n"
               "\n"
               "Generates a synthetic BTF with known ground truth (height field with self-shadowing,\n"
               "parallax, spatially varying albedo and roughness, cos(theta_light) included,\n"
               "sRGB-encoded 8-bit values) and writes it.\n"
               "  KIND              knit | tiles | stone\n"
               "  --size N          N x N texels, 1..4096 (default 256, the UBO2003 size)\n"
               "  --sampling S      light and view direction set (default ubo2003: 81 directions;\n"
               "                    dome151: UBO2014's 151; or a JSON ring table)\n"
               "  --seed S          random seed (default 1); the same seed gives the same material\n"
               "  --format F        png or jpg: UBO2003-named image directory OUT (default png;\n"
               "                    btf if OUT ends in .btf); btf: DFMF08FC file\n"
               "  --components C    DFMF factors per channel (default 0 = full rank, exact but\n"
               "                    large: about 4 * min(views*lights, N*N) * (views*lights + N*N) * 3 bytes)\n"
               "Images hold round(255 * value); the model is documented in bench/gen/btf_gen.h.\n");
    btf_args_exit_codes(f);
}

static int gen_ends_with(const char *s, const char *suffix)
{
    size_t n = strlen(s), m = strlen(suffix);
    return n >= m && !strcmp(s + n - m, suffix);
}

/* One option or positional of `btf gen` (btf_args_fn). */
static int gen_option(void *ctx, const btf_args *a, int c, const char *v)
{
    gen_opts *o = ctx;
    long seed;
    switch (c) {
    case BTF_ARG_POS:
        if (a->npos == 1)
            o->out = v;
        else if ((o->kind = btf_gen_kind_from_name(v)) < 0) {
            fprintf(stderr, "btf gen: unknown kind '%s' (knit, tiles, stone)\n", v);
            return 2;
        }
        break;
    case 'n': return btf_args_int(a, v, 1, 4096, &o->size);
    case 'r':
        if (!btf_arg_long(v, 0, 4294967295L, &seed))
            return btf_args_bad(a, v, "an integer 0..4294967295");
        o->seed = (unsigned)seed;
        break;
    case 's': o->sampling = v; break;
    case 'C': return btf_args_int(a, v, 0, 1000000, &o->components);
    case 'f': o->format = v; break;
    }
    return 0;
}

/* 0 ok, 2 usage error, -1 help printed. */
static int gen_parse(int argc, char **argv, gen_opts *o)
{
    static const btf_args_spec spec = {"gen", "size:n seed:r sampling:s components:C format:f", gen_usage, 2};
    memset(o, 0, sizeof *o);
    o->kind = -1, o->size = 256, o->seed = 1u, o->sampling = "ubo2003";
    int rc = btf_args_parse(&spec, argc, argv, gen_option, o);
    if (rc)
        return rc;
    if (!o->format)
        o->format = gen_ends_with(o->out, ".btf") ? "btf" : "png";
    if (strcmp(o->format, "png") && strcmp(o->format, "jpg") && strcmp(o->format, "btf")) {
        fprintf(stderr, "btf gen: unknown format '%s' (png, jpg, btf)\n", o->format);
        return 2;
    }
    return 0;
}

/* Image directory, one view at a time. */
static btf_result gen_write_images(const btf_gen_params *p, const btf_dirset *d, const gen_opts *o, btf_error *err)
{
    char prefix[64];
    const char *name = btf_gen_kind_name((btf_gen_kind)o->kind);
    snprintf(prefix, sizeof prefix, "Gen%c%s%d", toupper((unsigned char)name[0]), name + 1, o->size);
    btf_views s;
    btf_result r = btf_gen_views_open(p, o->size, o->size, d, d, &s, err);
    if (r == BTF_OK)
        r = btf_views_save_ubo2003(&s, o->out, prefix, o->format, err);
    btf_views_close(&s);
    return r;
}

/* The command once its options are parsed; the exit code. */
static int gen_main(void *opts)
{
    gen_opts *o = opts;
    btf_error err = {{0}};
    btf_dirset d;
    if (btf_source_sampling(o->sampling, &d, &err) != BTF_OK) {
        fprintf(stderr, "btf gen: %s\n", err.msg);
        return 1;
    }
    btf_gen_params p = btf_gen_defaults((btf_gen_kind)o->kind);
    p.seed = o->seed;
    btf *b = NULL;
    double t0 = btf_seconds();
    btf_result r = BTF_OK;
    if (!strcmp(o->format, "btf")) {
        r = btf_gen_create(&p, o->size, o->size, &d, &d, BTF_U8, &b, &err);
        if (r == BTF_OK)
            r = btf_save_dfmf(b, o->out, o->components, &err);
    } else {
        r = gen_write_images(&p, &d, o, &err);
    }
    double t1 = btf_seconds();
    btf_free(b);
    if (r != BTF_OK) {
        fprintf(stderr, "btf gen: %s\n", err.msg);
        return 1;
    }
    printf("%s: %s %dx%d, %d lights x %d views (%s), seed %u, %zu bytes of samples; "
           "generated and written (%s) in %.2f s\n",
           o->out, btf_gen_kind_name((btf_gen_kind)o->kind), o->size, o->size, d.n_dirs, d.n_dirs, o->sampling, o->seed,
           (size_t)o->size * o->size * 3 * d.n_dirs * d.n_dirs, o->format, t1 - t0);
    return 0;
}

int cmd_gen(int argc, char **argv)
{
    gen_opts o;
    return btf_args_finish(gen_parse(argc, argv, &o), gen_main, &o);
}
