/* cmd_import_thesis.c - `btf import-thesis DIR OUT [--size N] [--ext png|jpg]`:
 * reconstructs the full BTF from one of the thesis's published packages
 * (btf_import_thesis) and writes it as a UBO2003-named image directory, or as a
 * DFMF08FC file when OUT ends in `.btf` (full rank).
 *
 *     btf import-thesis ../shared/data/thesis-ubo2003/wool out/wool64 --size 64
 */
#include "btf_cli.h"
#include "btf_io.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void import_thesis_usage(FILE *f)
{
    fprintf(f, "usage: btf import-thesis DIR OUT [--size N] [--ext png|jpg]\n"
               "\n"
               "Reconstructs the BTF stored in a thesis package DIR (meta.json, 0.png.., R.png)\n"
               "with UBO2003 sampling, values clamped to 0..1 and stored as 8-bit, and writes it.\n"
               "  OUT          a directory of UBO2003-named images (one per light x view), or a\n"
               "               DFMF08FC file if OUT ends in .btf (full rank, float32)\n"
               "  --size N     N x N texels (default 256, the package's own size); sizes that\n"
               "               divide 256 are box-filtered, others area-weighted\n"
               "  --ext E      image format for a directory OUT: png (default) or jpg\n");
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

int cmd_import_thesis(int argc, char **argv)
{
    const char *pos[2] = {NULL, NULL}, *ext = "png";
    long size = 0;
    int npos = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
            import_thesis_usage(stdout);
            return 0;
        } else if (!strcmp(argv[i], "--size") && i + 1 < argc) {
            char *end;
            errno = 0;
            size = strtol(argv[++i], &end, 10);
            if (errno || *end || end == argv[i] || size < 1 || size > 4096) {
                fprintf(stderr, "btf import-thesis: --size must be 1..4096, got '%s'\n", argv[i]);
                return 2;
            }
        } else if (!strcmp(argv[i], "--ext") && i + 1 < argc) {
            ext = argv[++i];
            if (strcmp(ext, "png") && strcmp(ext, "jpg")) {
                fprintf(stderr, "btf import-thesis: --ext must be png or jpg, got '%s'\n", ext);
                return 2;
            }
        } else if (argv[i][0] == '-' || npos == 2) {
            fprintf(stderr, "btf import-thesis: unexpected argument '%s'\n", argv[i]);
            import_thesis_usage(stderr);
            return 2;
        } else {
            pos[npos++] = argv[i];
        }
    }
    if (npos != 2) {
        import_thesis_usage(stderr);
        return 2;
    }
    btf_load_options o = {0};
    o.width = o.height = (int)size;
    btf *b = NULL;
    btf_error e = {0};
    btf_result r = btf_import_thesis(pos[0], &o, &b, &e);
    if (r == BTF_OK) {
        if (import_thesis_ends_with(pos[1], ".btf")) {
            r = btf_save_dfmf(b, pos[1], 0, &e);
        } else {
            char prefix[256];
            import_thesis_prefix(pos[0], prefix, sizeof prefix);
            r = btf_save_ubo2003_dir(b, pos[1], prefix, ext, &e);
        }
    }
    if (r == BTF_OK)
        printf("%s: %dx%d texels, %d lights x %d views -> %s\n", pos[0], b->width, b->height, b->lights.n_dirs,
               b->views.n_dirs, pos[1]);
    btf_free(b);
    if (r != BTF_OK) {
        fprintf(stderr, "btf import-thesis: %s (%s)\n", e.msg, btf_result_string(r));
        return 1;
    }
    return 0;
}
