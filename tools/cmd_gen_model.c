/* cmd_gen_model.c - `btf gen-model OUT.glb`: the stool, a small glTF product of three
 * materials with known geometry (bench/gen/btf_gen_stool.h), for tests and the demo.
 *
 *     btf gen-model stool.glb
 *     btf render lib/wool stool.png --model stool.glb --bind Frame=lib/stone
 */
#include "btf_args.h"
#include "btf_cli.h"
#include "btf_gen_stool.h"

#include <stdio.h>
#include <string.h>

/* Parsed command line; stack value of cmd_gen_model, strings point into argv. */
typedef struct gen_model_opts {
    const char *out;
    int segments;
} gen_model_opts;

static void gen_model_usage(FILE *f)
{
    fprintf(f, "usage: btf gen-model OUT.glb [--segments N]\n"
               "\n"
               "Writes a stool as a binary glTF 2.0 file: a seat top (material \"Seat\", with\n"
               "tangents), its side band (\"Trim\") and four legs (\"Frame\", one mesh under four\n"
               "tilted nodes), +y up, about 1 unit across. Geometry: bench/gen/btf_gen_stool.h.\n"
               "  --segments N     subdivisions around, 3..120 (default 48)\n");
    btf_args_exit_codes(f);
}

static int gen_model_option(void *ctx, const btf_args *a, int c, const char *val)
{
    gen_model_opts *o = ctx;
    if (c == BTF_ARG_POS)
        o->out = val;
    else if (c == 's')
        return btf_args_int(a, val, 3, 120, &o->segments);
    return 0;
}

static int gen_model_main(void *opts)
{
    gen_model_opts *o = opts;
    btf_error err = {{0}};
    if (btf_gen_stool_write(o->out, o->segments, &err) != BTF_OK) {
        fprintf(stderr, "btf gen-model: %s\n", err.msg);
        return 1;
    }
    return 0;
}

int cmd_gen_model(int argc, char **argv)
{
    static const btf_args_spec spec = {"gen-model", "segments:s", gen_model_usage, 1};
    gen_model_opts o;
    memset(&o, 0, sizeof o);
    return btf_args_finish(btf_args_parse(&spec, argc, argv, gen_model_option, &o), gen_model_main, &o);
}
