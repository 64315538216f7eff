/* btf_input.c - the one place that names every input format: what kind of input
 * a path is (btf_input_kind_of) and the reader each kind goes to, whole
 * (btf_load_any, btf_io.h) or view by view (btf_views_open, btf_views.h). The
 * readers themselves (btf_ubo2003.c, btf_dfmf.c, btf_thesis.c) know none of the
 * others, nor this file. */
#include "btf_io.h"
#include "btf_views.h"
#include "btf_common.h"
#include "btf_input.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

/* 1 if dir holds a regular file (or a link to one) called name. */
static int btf__has_file(const char *dir, const char *name)
{
    size_t n = strlen(dir) + strlen(name) + 2;
    char *p = malloc(n);
    struct stat st;
    int ok = p && snprintf(p, n, "%s/%s", dir, name) > 0 && stat(p, &st) == 0 && S_ISREG(st.st_mode);
    free(p);
    return ok;
}

btf_result btf_input_kind_of(const char *path, btf_input_kind *kind, btf_error *err)
{
    struct stat st;
    if (stat(path, &st) != 0)
        return btf_fail(err, errno == ENOENT ? BTF_ERR_MISSING : BTF_ERR_IO, "%s: %s", path, strerror(errno));
    size_t n = strlen(path);
    if (S_ISREG(st.st_mode) && n >= 4 && !strcasecmp(path + n - 4, ".btf"))
        return *kind = BTF_INPUT_DFMF, BTF_OK;
    if (S_ISREG(st.st_mode))
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: unknown input (expected a .btf file or a directory)", path);
    if (!S_ISDIR(st.st_mode))
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: neither a file nor a directory", path);
    if (btf__has_file(path, "meta.json"))
        return *kind = BTF_INPUT_THESIS, BTF_OK;
    if (btf__has_file(path, "manifest.json"))
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: package: use the package API", path);
    return *kind = BTF_INPUT_IMAGES, BTF_OK;
}

btf_result btf_load_any(const char *path, const btf_load_options *opt, btf **out, btf_error *err)
{
    if (!path || !out)
        return btf_fail(err, BTF_ERR_ARG, "btf_load_any: NULL argument");
    *out = NULL;
    btf_input_kind kind;
    btf_result r = btf_input_kind_of(path, &kind, err);
    if (r != BTF_OK)
        return r;
    return kind == BTF_INPUT_DFMF     ? btf_load_dfmf(path, opt, out, err)
           : kind == BTF_INPUT_THESIS ? btf_import_thesis(path, opt, out, err)
                                      : btf_load_ubo2003_dir(path, opt, out, err);
}

btf_result btf_views_open(const char *path, const btf_load_options *opt, btf_views *out, btf_error *err)
{
    if (!path || !out)
        return btf_fail(err, BTF_ERR_ARG, "btf_views_open: NULL argument");
    memset(out, 0, sizeof *out);
    btf_input_kind kind;
    btf_result r = btf_input_kind_of(path, &kind, err);
    if (r != BTF_OK)
        return r;
    if (kind == BTF_INPUT_THESIS)
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: a thesis package is not read view by view (load it)", path);
    return kind == BTF_INPUT_DFMF ? btf_views_open_dfmf(path, opt, out, err) : btf_views_open_ubo2003(path, opt, out, err);
}
