/* btf_source.c - input names for the tools: "gen:KIND[:SIZE[:SEED]]" or a loadable path. */
#include "btf_source.h"

#include "btf_gen.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int source_field(const char **s, long lo, long hi, long *v)
{
    if (**s != ':')
        return 1; /* absent: keep default */
    char *end;
    errno = 0;
    long x = strtol(*s + 1, &end, 10);
    if (errno || end == *s + 1 || x < lo || x > hi || (*end && *end != ':'))
        return 0;
    *v = x;
    *s = end;
    return 1;
}

static btf_result source_gen(const char *spec, const btf_load_options *opt, btf **out, btf_error *err)
{
    const char *rest = spec + 4, *colon = strchr(rest, ':');
    size_t n = colon ? (size_t)(colon - rest) : strlen(rest);
    char kind_name[32];
    if (n == 0 || n >= sizeof kind_name)
        return btf_fail(err, BTF_ERR_ARG, "%s: expected gen:KIND[:SIZE[:SEED]]", spec);
    memcpy(kind_name, rest, n);
    kind_name[n] = 0;
    int kind = btf_gen_kind_from_name(kind_name);
    if (kind < 0)
        return btf_fail(err, BTF_ERR_ARG, "%s: unknown kind '%s' (knit, tiles, stone)", spec, kind_name);
    btf_gen_params p = btf_gen_defaults((btf_gen_kind)kind);
    long size = 64, seed = (long)p.seed;
    const char *s = rest + n;
    if (!source_field(&s, 1, BTF_MAX_SIDE, &size) || !source_field(&s, 0, 0x7fffffffL, &seed) || *s)
        return btf_fail(err, BTF_ERR_ARG, "%s: expected gen:KIND[:SIZE[:SEED]] with SIZE 1..%d", spec,
                        BTF_MAX_SIDE);
    p.seed = (unsigned)seed;
    btf_dirset d = opt && opt->sampling ? *opt->sampling : btf_dirset_ubo2003();
    btf_storage st = opt && opt->storage ? opt->storage : BTF_U8;
    btf *b = NULL;
    btf_result r = btf_gen_create(&p, (int)size, (int)size, &d, &d, st, &b, err);
    if (r == BTF_OK && opt && opt->downsample > 1) {
        btf *small = NULL;
        r = btf_downsample(b, opt->downsample, &small, err);
        btf_free(b);
        b = small;
    }
    *out = r == BTF_OK ? b : NULL;
    return r;
}

btf_result btf_source_load(const char *spec, const btf_load_options *opt, btf **out, btf_error *err)
{
    if (!spec || !out)
        return btf_fail(err, BTF_ERR_ARG, "btf_source_load: NULL argument");
    *out = NULL;
    if (!strncmp(spec, "gen:", 4))
        return source_gen(spec, opt, out, err);
    return btf_load_any(spec, opt, out, err);
}

btf_result btf_source_sampling(const char *name, btf_dirset *d, btf_error *err)
{
    if (!strcmp(name, "ubo2003"))
        *d = btf_dirset_ubo2003();
    else if (!strcmp(name, "dome151"))
        *d = btf_dirset_dome151();
    else
        return btf_dirset_load_json(name, d, err);
    return BTF_OK;
}

btf_result btf_source_load_args(const char *cmd, const char *spec, const btf_source_args *a, btf **out,
                                btf_error *err)
{
    btf_load_options lo = {0};
    btf_dirset set;
    int filled = 0;
    lo.downsample = a->downsample, lo.fill_missing = a->fill_missing, lo.n_filled = &filled;
    if (a->sampling) {
        btf_result r = btf_source_sampling(a->sampling, &set, err);
        if (r != BTF_OK)
            return r;
        lo.sampling = &set;
    }
    btf_result r = btf_source_load(spec, &lo, out, err);
    if (r == BTF_OK && filled > 0)
        fprintf(stderr, "btf %s: warning: %s: %d of %d images missing, interpolated from each view's nearest lights\n",
                cmd, spec, filled, (*out)->views.n_dirs * (*out)->lights.n_dirs);
    return r;
}
