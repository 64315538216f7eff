/* btfd_gzip.c - precompressed files on the file mounts (/ and /shaders/): a request
 * whose Accept-Encoding names gzip gets FILE.gz in place of FILE when the .gz lies
 * beside it as a regular file no older than FILE (`make build` writes them for the
 * client bundle), and libwebsockets adds `Content-Encoding: gzip` for a file opened
 * with LWS_FOP_FLAG_COMPR_IS_GZIP. Content-Type still follows FILE's name; every
 * file reply says `Vary: Accept-Encoding` (btfd_http.c) so caches keep both forms.
 */
#include <limits.h>
#include <stdio.h>
#include <sys/stat.h>

#include "btfd.h"

/* The platform's file operations (copied when the context is made) and the same with
 * the gzip-aware open; process-wide, set once by btfd_gzip_install. */
static struct lws_plat_file_ops plat_ops, gzip_ops;

/* A regular file at path, with its modification time. */
static int regular_file(const char *path, time_t *mtime)
{
    struct stat st;
    if (stat(path, &st) != 0 || !S_ISREG(st.st_mode))
        return 0;
    *mtime = st.st_mtime;
    return 1;
}

static lws_fop_fd_t gzip_open(const struct lws_plat_file_ops *fops, const char *filename, const char *vpath,
                              lws_fop_flags_t *flags)
{
    char gz[PATH_MAX];
    time_t t_file, t_gz;
    if ((*flags & LWS_FOP_FLAG_COMPR_ACCEPTABLE_GZIP) &&
        snprintf(gz, sizeof gz, "%s.gz", filename) < (int)sizeof gz &&
        regular_file(filename, &t_file) && regular_file(gz, &t_gz) && t_gz >= t_file) {
        lws_fop_flags_t f = *flags;
        lws_fop_fd_t fd = plat_ops.LWS_FOP_OPEN(fops, gz, vpath, &f);
        if (fd) {
            *flags = f | LWS_FOP_FLAG_COMPR_IS_GZIP;
            fd->flags = *flags;
            return fd;
        }
    }
    return plat_ops.LWS_FOP_OPEN(fops, filename, vpath, flags);
}

void btfd_gzip_install(struct lws_context *ctx)
{
    const struct lws_plat_file_ops *cur = lws_get_fops(ctx);
    if (cur->LWS_FOP_OPEN == gzip_open) /* a second context of this process */
        return;
    plat_ops = *cur;
    gzip_ops = plat_ops;
    gzip_ops.LWS_FOP_OPEN = gzip_open;
    lws_set_fops(ctx, &gzip_ops);
}
