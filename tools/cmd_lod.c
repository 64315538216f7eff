/* cmd_lod.c - `btf lod IN_PKG OUT_PKG`: adds spatial levels to a version-1 package
 * (doc/package-format.md section 10, codec/btf_lod.h).
 *
 *     btf lod lib/wool-v1 lib/wool --levels 4
 */
#include "btf_cli.h"
#include "btf_lod.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void lod_usage(FILE *f)
{
    fprintf(f, "usage: btf lod IN_PKG OUT_PKG [--levels N] [--threshold T] [--quiet]\n"
               "\n"
               "Writes OUT_PKG (a different directory) as package version 2: the version-1\n"
               "package IN_PKG plus per-component mip levels, chunks ordered coarse first.\n"
               "  --levels N      levels including level 0, 1..%d (default: as many as keep\n"
               "                  tiles >= 8 texels, at most 4); W and H must divide by 2^(N-1)\n"
               "  --threshold T   visibility threshold (RMS on 0..255) of the chunk order (default %.1f)\n",
            BTF_LOD_MAX_LEVELS, BTF_LOD_THRESHOLD);
}

/* Parses argv into o; 0 on a usage error. */
static int lod_args(int argc, char **argv, const char **in, const char **out, btf_lod_options *o, int *quiet)
{
    int npos = 0;
    for (int i = 1; i < argc; i++) {
        char *end = NULL;
        errno = 0;
        if (!strcmp(argv[i], "--levels") && i + 1 < argc) {
            long x = strtol(argv[++i], &end, 10);
            if (errno || *end || x < 1 || x > BTF_LOD_MAX_LEVELS)
                return 0;
            o->levels = (int)x;
        } else if (!strcmp(argv[i], "--threshold") && i + 1 < argc) {
            o->threshold = strtod(argv[++i], &end);
            if (errno || *end || !(o->threshold > 0.0) || o->threshold > 1e6)
                return 0;
        } else if (!strcmp(argv[i], "--quiet")) {
            *quiet = 1;
        } else if (argv[i][0] == '-' || npos == 2) {
            return 0;
        } else {
            *(npos++ ? out : in) = argv[i];
        }
    }
    return npos == 2;
}

int cmd_lod(int argc, char **argv)
{
    const char *in = NULL, *out = NULL;
    btf_lod_options o = {0};
    int quiet = 0;
    if (argc >= 2 && (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h"))) {
        lod_usage(stdout);
        return 0;
    }
    if (!lod_args(argc, argv, &in, &out, &o, &quiet)) {
        lod_usage(stderr);
        return 2;
    }
    btf_lod_stats st = {0};
    btf_error err = {0};
    if (btf_lod_build(in, out, &o, &st, &err) != BTF_OK) {
        fprintf(stderr, "btf lod: %s\n", err.msg);
        return 1;
    }
    if (!quiet)
        printf("%s: %d levels, %d chunks, %lld bytes (version 1: %lld), first chunk %lld bytes\n", out, st.levels,
               st.n_chunks, st.bytes, st.bytes_v1, st.first_chunk);
    return 0;
}
