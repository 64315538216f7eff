/* btf_source.c - input names for the tools: "gen:KIND[:SIZE[:SEED]]" or a loadable path. */
#include "btf_source.h"

#include "btf_gen.h"
#include "btf_common.h"

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

/* Parses gen:KIND[:SIZE[:SEED]] into parameters and a size. */
static btf_result source_gen_spec(const char *spec, btf_gen_params *out, long *size_out, btf_error *err)
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
    *out = p, *size_out = size;
    return BTF_OK;
}

static btf_result source_gen(const char *spec, const btf_load_options *opt, btf **out, btf_error *err)
{
    btf_gen_params p;
    long size;
    btf_result gr = source_gen_spec(spec, &p, &size, err);
    if (gr != BTF_OK)
        return gr;
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

void btf_source_warn(const char *cmd, const char *spec, int n_filled, int n_images, const btf_load_report *rep)
{
    if (n_filled > 0)
        fprintf(stderr, "btf %s: warning: %s: %d of %d images missing, interpolated from each view's nearest lights\n",
                cmd, spec, n_filled, n_images);
    if (rep && rep->n_images_clipped > 0)
        fprintf(stderr,
                "btf %s: warning: %s: clipped highlights: %lld of %lld samples (%.2f%%) are 255, in %d images with at "
                "least %.0f%%; most in %s (%.1f%%); errors are measured against the clipped values\n",
                cmd, spec, rep->n_saturated, rep->n_samples, 100.0 * (double)rep->n_saturated / (double)rep->n_samples,
                rep->n_images_clipped, 100.0 * BTF_LOAD_CLIPPED_SHARE, rep->worst_file,
                100.0 * (double)rep->worst_saturated / (double)(rep->worst_samples > 0 ? rep->worst_samples : 1));
}

/* The loader options a set of input arguments gives; set holds the sampling. */
static btf_result source_options(const btf_source_args *a, btf_dirset *set, btf_load_options *lo, btf_error *err)
{
    memset(lo, 0, sizeof *lo);
    lo->downsample = a->downsample, lo->fill_missing = a->fill_missing, lo->storage = a->storage;
    lo->width = a->width, lo->height = a->height;
    if (!a->sampling)
        return BTF_OK;
    lo->sampling = set;
    return btf_source_sampling(a->sampling, set, err);
}

btf_result btf_source_load_args(const char *cmd, const char *spec, const btf_source_args *a, btf **out,
                                btf_error *err)
{
    btf_load_options lo;
    btf_dirset set;
    btf_load_report rep;
    memset(&rep, 0, sizeof rep);
    int filled = 0;
    btf_result r = source_options(a, &set, &lo, err);
    lo.n_filled = &filled, lo.report = &rep;
    if (r == BTF_OK)
        r = btf_source_load(spec, &lo, out, err);
    if (r == BTF_OK)
        btf_source_warn(cmd, spec, filled, (*out)->views.n_dirs * (*out)->lights.n_dirs, &rep);
    return r;
}

btf_result btf_source_open_views(const char *spec, const btf_source_args *a, btf_views *out, btf_error *err)
{
    btf_load_options lo;
    btf_dirset set;
    memset(out, 0, sizeof *out);
    btf_result r = source_options(a, &set, &lo, err);
    if (r != BTF_OK)
        return r;
    if (strncmp(spec, "gen:", 4) != 0)
        return btf_views_open(spec, &lo, out, err);
    if (a->downsample > 1)
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: generated whole for --downsample", spec);
    btf_gen_params p;
    long size;
    r = source_gen_spec(spec, &p, &size, err);
    if (r != BTF_OK)
        return r;
    btf_dirset d = a->sampling ? set : btf_dirset_ubo2003();
    r = btf_gen_views_open(&p, (int)size, (int)size, &d, &d, out, err);
    if (r == BTF_OK)
        out->name = spec;
    return r;
}

btf_result btf_source_open(const char *cmd, const char *spec, const btf_source_args *a, int whole,
                           btf_source_input *in, btf_error *err)
{
    memset(in, 0, sizeof *in);
    btf_result r = whole ? BTF_ERR_UNSUPPORTED : btf_source_open_views(spec, a, &in->views, err);
    if (r == BTF_ERR_UNSUPPORTED)
        r = btf_source_load_args(cmd, spec, a, &in->whole, err);
    if (in->whole)
        btf_views_wrap(in->whole, &in->views);
    return r;
}

void btf_source_warn_views(const char *cmd, const char *spec, const btf_source_input *in)
{
    const btf_views *v = &in->views;
    if (!in->whole)
        btf_source_warn(cmd, spec, v->n_filled, v->views.n_dirs * v->lights.n_dirs, &v->report);
}

void btf_source_close(btf_source_input *in)
{
    btf_views_close(&in->views);
    btf_free(in->whole);
    memset(in, 0, sizeof *in);
}
