/* btf_args.c - command-line parsing shared by the `btf` subcommands (btf_args.h). */
#include "btf_args.h"
#include "btf_common.h"

#include <errno.h>
#include <getopt.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

int btf_arg_long(const char *s, long lo, long hi, long *v)
{
    if (!s)
        return 0;
    char *end;
    errno = 0;
    long x = strtol(s, &end, 10);
    if (errno || end == s || *end || x < lo || x > hi)
        return 0;
    *v = x;
    return 1;
}

int btf_arg_int(const char *s, long lo, long hi, int *v)
{
    long x;
    if (!btf_arg_long(s, lo, hi, &x))
        return 0;
    *v = (int)x;
    return 1;
}

int btf_arg_enum(const char *s, const char *const *names, int n, int *v)
{
    int i = btf_name_index(names, n, s);
    if (i >= 0)
        *v = i;
    return i >= 0;
}

void btf_args_exit_codes(FILE *f)
{
    fprintf(f, "Exit status: 0 ok, 1 failure, 2 usage error.\n");
}

int btf_args_bad(const btf_args *a, const char *val, const char *what, ...)
{
    va_list ap;
    va_start(ap, what);
    fprintf(stderr, "btf %s: %s %s: expected ", a->spec->cmd, a->opt, val ? val : "(none)");
    vfprintf(stderr, what, ap);
    fputc('\n', stderr);
    va_end(ap);
    return 2;
}

int btf_args_int(const btf_args *a, const char *val, long lo, long hi, int *v)
{
    return btf_arg_int(val, lo, hi, v) ? 0 : btf_args_bad(a, val, "an integer %ld..%ld", lo, hi);
}

int btf_args_long(const btf_args *a, const char *val, long lo, long hi, long long *v)
{
    long x;
    if (!btf_arg_long(val, lo, hi, &x))
        return btf_args_bad(a, val, "an integer %ld..%ld", lo, hi);
    *v = x;
    return 0;
}

int btf_args_double(const btf_args *a, const char *val, double lo, double hi, double *v)
{
    char *end = NULL;
    errno = 0;
    double x = val ? strtod(val, &end) : 0.0;
    if (!val || errno || end == val || *end || !(x >= lo && x <= hi))
        return btf_args_bad(a, val, "a number %g..%g", lo, hi);
    *v = x;
    return 0;
}

int btf_args_enum(const btf_args *a, const char *val, const char *const *names, int n, int *v)
{
    if (btf_arg_enum(val, names, n, v))
        return 0;
    char list[256] = "";
    for (int i = 0; i < n; i++)
        snprintf(list + strlen(list), sizeof list - strlen(list), "%s%s", i ? "|" : "", names[i]);
    return btf_args_bad(a, val, "%s", list);
}

int btf_args_pca(const btf_args *a, int c, const char *val, const btf_args_pca_dst *d)
{
    static const char *const methods[] = {"auto", "gram", "randomized", "svd"};
    int e = 0, rc = 0;
    switch (c) {
    case 'k': rc = btf_args_int(a, val, 1, BTF_MAX_DIRS, d->k); break;
    case 'C': rc = btf_args_int(a, val, 1, d->max_components, d->components); break;
    }
    if (rc == 0 && d->budget && c == 'k')
        d->budget->k[0] = *d->k, d->budget->n_k = 1;
    if (rc == 0 && d->budget && c == 'C')
        d->budget->max_components = *d->components;
    switch (c) {
    case 'm': rc = btf_args_enum(a, val, methods, 4, &e), *d->method = (btf_pca_method)e; break;
    case 'd': rc = btf_args_int(a, val, 1, 256, d->downsample); break;
    }
    return rc;
}

/* getopt_long's complaint ('?' or ':') about argv[optind-1] as our message; returns 2. */
static int btf__args_complaint(const btf_args *a, int c, char **argv)
{
    const char *arg = argv[optind - 1], *cmd = a->spec->cmd;
    if (c == ':')
        fprintf(stderr, "btf %s: option '%s' needs a value\n", cmd, arg);
    else if (strncmp(arg, "--", 2))
        fprintf(stderr, "btf %s: unknown option '-%c'\n", cmd, optopt);
    else if (optopt)
        fprintf(stderr, "btf %s: option '%.*s' takes no value\n", cmd, (int)strcspn(arg, "="), arg);
    else
        fprintf(stderr, "btf %s: unknown or ambiguous option '%s'\n", cmd, arg);
    return 2;
}

/* One positional: its count checked against spec->n_pos, then fn. */
static int btf__args_pos(btf_args *a, const char *val, btf_args_fn fn, void *ctx)
{
    if (a->spec->n_pos >= 0 && a->npos >= a->spec->n_pos) {
        fprintf(stderr, "btf %s: unexpected argument '%s'\n", a->spec->cmd, val);
        return 2;
    }
    snprintf(a->opt, sizeof a->opt, "%s", val);
    int rc = fn(ctx, a, BTF_ARG_POS, val);
    a->npos++;
    return rc;
}

/* getopt_long's table from spec->opts; the names point into names (a copy). A
 * one-letter NAME is also the short option -NAME (its code must be that letter),
 * added to shorts (which starts as "-:h"). */
static void btf__args_table(const char *spec, char *names, size_t n, struct option *t, char shorts[16])
{
    snprintf(names, n, "%s", spec);
    snprintf(shorts, 16, "-:h");
    int k = 0;
    t[k++] = (struct option){"help", no_argument, NULL, 'h'};
    char *save = NULL;
    for (char *s = strtok_r(names, " ", &save); s && k < BTF_ARGS_MAX; s = strtok_r(NULL, " ", &save)) {
        size_t len = strcspn(s, ":!");
        if (!s[len] || !s[len + 1])
            continue; /* malformed entry: no code */
        if (len == 1 && s[2] == s[0] && strlen(shorts) < 13)
            snprintf(shorts + strlen(shorts), 4, "%c%s", s[0], s[1] == ':' ? ":" : "");
        t[k++] = (struct option){s, s[len] == ':' ? required_argument : no_argument, NULL, s[len + 1]};
        s[len] = '\0';
    }
    t[k] = (struct option){NULL, 0, NULL, 0};
}

int btf_args_parse(const btf_args_spec *spec, int argc, char **argv, btf_args_fn fn, void *ctx)
{
    btf_args a = {spec, "", 0};
    struct option opts[BTF_ARGS_MAX + 1];
    char names[1024], shorts[16];
    btf__args_table(spec->opts, names, sizeof names, opts, shorts);
    int c, li, rc = 0;
    optind = 0; /* GNU: re-initialise (commands run one after another in one process) */
    opterr = 0;
    /* "-": positionals come back in order as code 1; ":": a missing value is ':' */
    while (rc == 0 && (li = -1, c = getopt_long(argc, argv, shorts, opts, &li)) != -1) {
        if (c == 'h') {
            spec->usage(stdout);
            return -1;
        }
        if (c == '?' || c == ':')
            return btf__args_complaint(&a, c, argv);
        if (c == BTF_ARG_POS) {
            rc = btf__args_pos(&a, optarg, fn, ctx);
            continue;
        }
        snprintf(a.opt, sizeof a.opt, "--%s", li >= 0 ? opts[li].name : "?");
        rc = fn(ctx, &a, c, optarg);
    }
    for (int i = optind; rc == 0 && i < argc; i++) /* after "--" */
        rc = btf__args_pos(&a, argv[i], fn, ctx);
    if (rc == 0 && spec->n_pos >= 0 && a.npos < spec->n_pos) {
        spec->usage(stderr);
        return 2;
    }
    return rc;
}

int btf_args_finish(int rc, int (*run)(void *opts), void *opts)
{
    return rc < 0 ? 0 : rc > 0 ? rc : run(opts);
}
