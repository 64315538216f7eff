/* btfd_publish.c - the library as files for a static host: `btfd --library LIB --publish OUT`
 * (`btf library publish LIB OUT` runs it). What btfd answers over HTTP, as files at the
 * same paths, so a client builds its URLs one way for both (doc/protocol.md section 1):
 *
 *   OUT/materials.json                  the list, the body GET /materials (and /materials.json) answers
 *   OUT/materials/NAME/thumbnail.png    the poster, when the package has one
 *   OUT/materials/NAME/ETAG/FILE        manifest.json, thumbnail.png and every file of its chunks
 *   OUT/FILE.js, OUT/FILE.js.gz         the scripts of the --client folder (the bundle, build/client)
 *
 * The library is read by the code btfd serves it with (btfd_library.c: the same packages
 * skipped, the same etags and summaries). Every file is written atomically (temp + fsync +
 * rename) and only when its bytes differ from what is there, the list last, so the list
 * never names a file that is not there yet. Nothing is removed: the files of an older etag
 * stay where a page that cached the older list looks for them (ETAG paths never change
 * their bytes), and a second run over an unchanged library writes nothing.
 */
#include <dirent.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "btf_fs.h"
#include "btfd.h"

/* What one run did (printed at the end). Stack value of btfd_publish. */
typedef struct publish_counts {
    int written, unchanged, failed;
} publish_counts;

/* buf = "a/b"; 0, or -1 (and a message) when it does not fit. */
static int join(char *buf, size_t n, const char *a, const char *b)
{
    int len = snprintf(buf, n, "%s/%s", a, b);
    if (len > 0 && (size_t)len < n)
        return 0;
    fprintf(stderr, "btfd: %s/%s: path too long\n", a, b);
    return -1;
}

/* mkdir that accepts an existing directory; the parent's entry is synced when it is new. */
static int make_dir(const char *path, const char *parent)
{
    if (mkdir(path, 0755) == 0) {
        btf_error err;
        btf_fs_sync_dir(parent, &err);
        return 0;
    }
    struct stat st;
    if (errno == EEXIST && stat(path, &st) == 0 && S_ISDIR(st.st_mode))
        return 0;
    fprintf(stderr, "btfd: %s: cannot make the folder (%s)\n", path, strerror(errno));
    return -1;
}

/* 1 when path holds exactly these n bytes. */
static int same_bytes(const char *path, const void *data, size_t n)
{
    if (btf_fs_size(path) != (long long)n)
        return 0;
    char *have = NULL;
    size_t len = 0;
    btf_error err;
    if (btf_fs_read(path, n + 1, &have, &len, &err) != BTF_OK)
        return 0;
    int same = len == n && (n == 0 || memcmp(have, data, n) == 0);
    free(have);
    return same;
}

/* Writes path (temp + fsync + rename) unless it holds these bytes already. */
static void put_file(const char *path, const void *data, size_t n, publish_counts *c)
{
    if (same_bytes(path, data, n)) {
        c->unchanged++;
        return;
    }
    btf_error err = {0};
    if (btf_fs_write_atomic(path, data, n, &err) == BTF_OK) {
        c->written++;
    } else {
        fprintf(stderr, "btfd: %s\n", err.msg);
        c->failed++;
    }
}

/* OUT/materials/NAME/{thumbnail.png, ETAG/...} of one package. */
static void publish_material(const char *mats, const btfd_material *m, publish_counts *c)
{
    char dir[BTF_FS_PATH_MAX], edir[BTF_FS_PATH_MAX], path[BTF_FS_PATH_MAX];
    if (join(dir, sizeof dir, mats, m->name) || join(edir, sizeof edir, dir, m->etag) || make_dir(dir, mats) ||
        make_dir(edir, dir)) {
        c->failed++;
        return;
    }
    for (int i = 0; i < m->n_chunks; i++)
        for (int f = 0; f < m->chunks[i].n_files; f++) {
            const btfd_file *bf = &m->chunks[i].files[f];
            if (join(path, sizeof path, edir, bf->name) == 0)
                put_file(path, bf->data, bf->size, c);
            else
                c->failed++;
        }
    if (m->thumb && join(path, sizeof path, edir, "thumbnail.png") == 0)
        put_file(path, m->thumb, m->thumb_size, c);
    if (join(path, sizeof path, edir, "manifest.json") == 0) /* last: the package is whole once it is there */
        put_file(path, m->manifest, m->manifest_len, c);
    if (m->thumb && join(path, sizeof path, dir, "thumbnail.png") == 0)
        put_file(path, m->thumb, m->thumb_size, c);
}

/* Whether name is a script (*.js) or its gzipped copy (*.js.gz, for a host that serves it
 * to a browser that accepts gzip: nginx's gzip_static). */
static int client_script(const char *name)
{
    size_t n = strlen(name);
    return name[0] != '.' && !strstr(name, ".tmp-") &&
           ((n > 3 && !strcmp(name + n - 3, ".js")) || (n > 6 && !strcmp(name + n - 6, ".js.gz")));
}

/* The scripts of the client folder (regular *.js files at its top and their .js.gz; not
 * the demo pages). */
static void publish_client(const char *client, const char *out, publish_counts *c)
{
    DIR *d = opendir(client);
    if (!d) {
        fprintf(stderr, "btfd: %s: %s (no client files published)\n", client, strerror(errno));
        c->failed++;
        return;
    }
    struct dirent *e;
    while ((e = readdir(d))) {
        char src[BTF_FS_PATH_MAX], dst[BTF_FS_PATH_MAX];
        if (!client_script(e->d_name))
            continue;
        if (join(src, sizeof src, client, e->d_name) || join(dst, sizeof dst, out, e->d_name)) {
            c->failed++;
            continue;
        }
        char *data = NULL;
        size_t len = 0;
        btf_error err = {0};
        if (btf_fs_size(src) < 0)
            continue; /* not a regular file */
        if (btf_fs_read(src, 256u << 20, &data, &len, &err) != BTF_OK) {
            fprintf(stderr, "btfd: %s\n", err.msg);
            c->failed++;
            continue;
        }
        put_file(dst, data, len, c);
        free(data);
    }
    closedir(d);
}

int btfd_publish(const btfd_options *o, btfd_library *lib, const char *out)
{
    publish_counts c = {0};
    char mats[BTF_FS_PATH_MAX], path[BTF_FS_PATH_MAX];
    if (join(mats, sizeof mats, out, "materials") || join(path, sizeof path, out, "materials.json"))
        return 1;
    if (mkdir(out, 0755) != 0 && errno != EEXIST) {
        fprintf(stderr, "btfd: %s: cannot make the folder (%s)\n", out, strerror(errno));
        return 1;
    }
    if (make_dir(mats, out))
        return 1;
    for (int i = 0; i < lib->n; i++)
        publish_material(mats, lib->items[i], &c);
    if (o->client_dir && o->client_dir[0])
        publish_client(o->client_dir, out, &c);
    char *list = btfd_library_list_body(lib);
    if (!list) {
        fprintf(stderr, "btfd: out of memory\n");
        return 1;
    }
    if (c.failed)
        fprintf(stderr, "btfd: %s not updated: %d files failed\n", path, c.failed);
    else
        put_file(path, list, strlen(list), &c);
    free(list);
    printf("btfd: published %d materials to %s: %d files written, %d unchanged, %d failed\n", lib->n, out, c.written,
           c.unchanged, c.failed);
    return c.failed ? 1 : 0;
}
