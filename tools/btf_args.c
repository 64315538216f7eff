/* btf_args.c - option value parsing shared by the `btf` subcommands. */
#include "btf_args.h"

#include <errno.h>
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
    for (int i = 0; s && i < n; i++)
        if (!strcmp(s, names[i])) {
            *v = i;
            return 1;
        }
    return 0;
}
