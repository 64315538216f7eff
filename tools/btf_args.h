/* btf_args.h - option value parsing shared by the `btf` subcommands. */
#ifndef BTF_ARGS_H
#define BTF_ARGS_H

/* Whole decimal number in lo..hi into *v; 0 (and *v untouched) if s is NULL or bad. */
int btf_arg_long(const char *s, long lo, long hi, long *v);
/* Same into an int (lo..hi must fit an int). */
int btf_arg_int(const char *s, long lo, long hi, int *v);
/* Index of s in names[0..n-1] into *v; 0 if s is NULL or not listed. */
int btf_arg_enum(const char *s, const char *const *names, int n, int *v);

#endif
