/* btf_args.h - command-line parsing shared by the `btf` subcommands: getopt_long
 * over argv (so `--k 3` and `--k=3` both work, positionals anywhere), option
 * value checks, and the one form of their error messages.
 *
 *     static const btf_args_spec spec = {"compress", "k:k components:C quiet!q", compress_usage, 2};
 *     int rc = btf_args_parse(&spec, argc, argv, compress_option, &o);
 *
 * Exit codes of every command (tools/btf_cli.h): 0 ok, 1 failure, 2 usage error.
 */
#ifndef BTF_ARGS_H
#define BTF_ARGS_H

#include "btf_budget.h"
#include "btf_pca.h"

#include <stdio.h>

/* Option code of a positional argument (val = the argument). */
#define BTF_ARG_POS 1
/* Most options one command may have (--help included). */
#define BTF_ARGS_MAX 32

/* One command's options; static const value in its cmd_NAME.c. */
typedef struct btf_args_spec {
    const char *cmd;        /* "compress": messages read "btf compress: ..." */
    const char *opts;       /* space-separated "NAME:C" (takes a value) or "NAME!C" (a flag), C the
                             * code passed to the callback; a one-letter NAME whose C is that
                             * letter is also -NAME ("j:j": -j 4); -h and --help are always there */
    void (*usage)(FILE *f); /* the command's --help text */
    int n_pos;              /* positionals wanted, exactly; -1: any number */
} btf_args_spec;

/* Where the parse is; stack value of btf_args_parse, valid during a callback. */
typedef struct btf_args {
    const btf_args_spec *spec;
    char opt[64]; /* the option being handled, as "--k" */
    int npos;     /* positionals before this one */
} btf_args;

/* Called for each option (code = its val; value NULL when it takes none) and each
 * positional (code BTF_ARG_POS, a->npos its index); 0 goes on, other values stop
 * the parse and are returned (2 = usage error, message printed). */
typedef int (*btf_args_fn)(void *ctx, const btf_args *a, int code, const char *val);

/* Parses argv[1..argc-1] (argv[0] = the command). -h/--help prints the usage on
 * stdout and returns -1; an unknown option, a missing value, too many or too few
 * positionals print a message and return 2; else fn's first nonzero value, or 0. */
int btf_args_parse(const btf_args_spec *spec, int argc, char **argv, btf_args_fn fn, void *ctx);
/* A command's exit code from its parse result: rc < 0 (--help shown) 0, rc > 0
 * that usage error, 0 run(opts). The one entry shape of every cmd_NAME. */
int btf_args_finish(int rc, int (*run)(void *opts), void *opts);

/* Prints "btf CMD: --opt VALUE: expected WHAT" (WHAT printf-style) to stderr; returns 2. */
int btf_args_bad(const btf_args *a, const char *val, const char *what, ...) __attribute__((format(printf, 3, 4)));
/* Integer lo..hi into *v: 0, or 2 after btf_args_bad. */
int btf_args_int(const btf_args *a, const char *val, long lo, long hi, int *v);
/* The same into a long long, and a finite number lo..hi into a double. */
int btf_args_long(const btf_args *a, const char *val, long lo, long hi, long long *v);
int btf_args_double(const btf_args *a, const char *val, double lo, double hi, double *v);
/* Index of val in names[0..n-1] into *v: 0, or 2 after btf_args_bad listing the names. */
int btf_args_enum(const btf_args *a, const char *val, const char *const *names, int n, int *v);
/* Where btf_args_pca stores; stack value of the caller, pointing into its option struct. */
typedef struct btf_args_pca_dst {
    int *k, *components, *downsample;
    btf_pca_method *method;
    int max_components;
    btf_budget *budget; /* NULL, or the budget whose k / component count --k / --components fix */
} btf_args_pca_dst;
/* The PCA options of compress and export-thesis: codes k (--k 1..BTF_MAX_DIRS), C
 * (--components 1..max_components), m (--method auto|gram|randomized|svd), d
 * (--downsample 1..256); other codes are ignored. With d->budget, --k makes k the
 * budget's only candidate and --components its fixed component count. 0 ok, 2 usage error. */
int btf_args_pca(const btf_args *a, int c, const char *val, const btf_args_pca_dst *d);
/* The exit-code lines every --help ends with. */
void btf_args_exit_codes(FILE *f);

/* Whole decimal number in lo..hi into *v; 0 (and *v untouched) if s is NULL or bad. */
int btf_arg_long(const char *s, long lo, long hi, long *v);
/* Same into an int (lo..hi must fit an int). */
int btf_arg_int(const char *s, long lo, long hi, int *v);
/* Index of s in names[0..n-1] into *v; 0 if s is NULL or not listed. */
int btf_arg_enum(const char *s, const char *const *names, int n, int *v);

#endif
