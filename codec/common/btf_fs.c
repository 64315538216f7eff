/* btf_fs.c - bounded reads, atomic writes, atomic directory replacement, tree removal. */
#define _GNU_SOURCE /* renameat2, nftw's FTW_PHYS */
#include "btf_fs.h"
#include "btf_common.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <ftw.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* The refusal of a file of n bytes over a read's max_bytes (disk and memory alike). */
static btf_result btf__fs_over(const char *path, unsigned long long n, size_t max_bytes, btf_error *err)
{
    return btf_fail(err, BTF_ERR_RANGE, "%s: %llu bytes, larger than the limit of %zu", path, n, max_bytes);
}

btf_result btf_fs_read(const char *path, size_t max_bytes, char **out, size_t *size, btf_error *err)
{
    *out = NULL;
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    struct stat st;
    if (fd < 0)
        return btf_fail(err, errno == ENOENT ? BTF_ERR_MISSING : BTF_ERR_IO, "%s: cannot open (%s)", path,
                        strerror(errno));
    if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
        close(fd);
        return btf_fail(err, BTF_ERR_IO, "%s: not a regular file", path);
    }
    if ((unsigned long long)st.st_size > max_bytes) {
        close(fd);
        return btf__fs_over(path, (unsigned long long)st.st_size, max_bytes, err);
    }
    size_t n = (size_t)st.st_size, got = 0;
    char *buf = malloc(n + 1);
    while (buf && got < n) {
        ssize_t r = read(fd, buf + got, n - got);
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0)
            break;
        got += (size_t)r;
    }
    close(fd);
    if (!buf)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory (%zu bytes)", path, n + 1);
    if (got != n) {
        free(buf);
        return btf_fail(err, BTF_ERR_IO, "%s: read failed", path);
    }
    buf[n] = 0;
    if (size)
        *size = n;
    *out = buf;
    return BTF_OK;
}

long long btf_fs_size(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 && S_ISREG(st.st_mode) ? (long long)st.st_size : -1;
}

btf_result btf_fs_read_with(const btf_files *files, const char *path, size_t max_bytes, char **out, size_t *size,
                            btf_error *err)
{
    if (!files || !files->read)
        return btf_fs_read(path, max_bytes, out, size, err);
    *out = NULL;
    size_t n = 0;
    btf_result r = files->read(files->user, path, max_bytes, out, &n, err);
    if (r == BTF_OK && size)
        *size = n;
    return r;
}

long long btf_fs_size_with(const btf_files *files, const char *path)
{
    return files && files->size ? files->size(files->user, path) : btf_fs_size(path);
}

/* ---------------------------------------------------------------- files in memory */

/* The entry of m named as path's last element, or NULL. */
static const btf_fs_mem_file *btf__fs_mem_find(const btf_fs_mem *m, const char *path)
{
    const char *slash = strrchr(path, '/'), *name = slash ? slash + 1 : path;
    for (int i = 0; i < m->n; i++)
        if (m->file[i].name && !strcmp(m->file[i].name, name))
            return &m->file[i];
    return NULL;
}

/* A malloc'd copy of n bytes (one more, zero, so a text is a string); NULL when out of memory. */
static char *btf__fs_copy(const void *data, size_t n)
{
    char *c = malloc(n + 1);
    if (c) {
        if (n)
            memcpy(c, data, n);
        c[n] = 0;
    }
    return c;
}

/* btf_files.read over a btf_fs_mem: a copy, refused as btf_fs_read refuses a file. */
static btf_result btf__fs_mem_read(void *user, const char *path, size_t max_bytes, char **out, size_t *size,
                                   btf_error *err)
{
    const btf_fs_mem_file *f = btf__fs_mem_find(user, path);
    *out = NULL;
    if (!f)
        return btf_fail(err, BTF_ERR_MISSING, "%s: cannot open (%s)", path, strerror(ENOENT));
    if (f->size > max_bytes)
        return btf__fs_over(path, f->size, max_bytes, err);
    if (!(*out = btf__fs_copy(f->data, f->size)))
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory (%zu bytes)", path, f->size + 1);
    *size = f->size;
    return BTF_OK;
}

static long long btf__fs_mem_size(void *user, const char *path)
{
    const btf_fs_mem_file *f = btf__fs_mem_find(user, path);
    return f ? (long long)f->size : -1;
}

btf_files btf_fs_mem_files(const btf_fs_mem *m)
{
    btf_files f = {btf__fs_mem_read, btf__fs_mem_size, (void *)m};
    return f;
}

/* Entry i of d, writable (d made every entry). */
static btf_fs_mem_file *btf__fs_memdir_at(btf_fs_memdir *d, int i)
{
    return (btf_fs_mem_file *)&d->mem.file[i];
}

btf_result btf_fs_memdir_put(void *user, const char *name, const void *data, size_t n, btf_error *err)
{
    btf_fs_memdir *d = user;
    const btf_fs_mem_file *was = btf__fs_mem_find(&d->mem, name);
    int i = was ? (int)(was - d->mem.file) : d->mem.n;
    if (!was && d->mem.n == d->cap) {
        int cap = d->cap ? 2 * d->cap : 16;
        void *f = realloc((void *)d->mem.file, (size_t)cap * sizeof *d->mem.file);
        if (!f)
            return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", name);
        d->mem.file = f, d->cap = cap;
    }
    char *nm = was ? NULL : btf__fs_copy(name, strlen(name)), *bytes = btf__fs_copy(data, n);
    if (!bytes || (!was && !nm)) {
        free(nm), free(bytes);
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory (%zu bytes)", name, n);
    }
    btf_fs_mem_file *f = btf__fs_memdir_at(d, i);
    if (was)
        free((void *)f->data);
    else
        f->name = nm, d->mem.n++;
    f->data = bytes, f->size = n;
    return BTF_OK;
}

void btf_fs_memdir_free(btf_fs_memdir *d)
{
    for (int i = 0; i < d->mem.n; i++) {
        btf_fs_mem_file *f = btf__fs_memdir_at(d, i);
        free((void *)f->name), free((void *)f->data);
    }
    free((void *)d->mem.file);
    memset(d, 0, sizeof *d);
}

/* The directory part of path into buf ("." when there is none). */
static void btf__fs_dirname(const char *path, char *buf, size_t n)
{
    const char *slash = strrchr(path, '/');
    if (!slash)
        snprintf(buf, n, ".");
    else if (slash == path)
        snprintf(buf, n, "/");
    else
        snprintf(buf, n, "%.*s", (int)(slash - path), path);
}

btf_result btf_fs_sync_dir(const char *dir, btf_error *err)
{
    int fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0)
        return btf_fail(err, BTF_ERR_IO, "%s: cannot open directory (%s)", dir, strerror(errno));
    int rc = fsync(fd);
    int e = errno;
    close(fd);
    if (rc != 0 && e != EINVAL && e != ENOTSUP) /* some file systems cannot sync directories */
        return btf_fail(err, BTF_ERR_IO, "%s: fsync failed (%s)", dir, strerror(e));
    return BTF_OK;
}

btf_result btf_fs_temp_name(const char *path, char *buf, size_t n, btf_error *err)
{
    int len = snprintf(buf, n, "%s.tmp-%ld", path, (long)getpid());
    return len > 0 && (size_t)len < n ? BTF_OK : btf_fail(err, BTF_ERR_ARG, "%s: path too long", path);
}

/* fsync of an existing file by name. */
static btf_result btf__fs_sync_file(const char *path, btf_error *err)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return btf_fail(err, BTF_ERR_IO, "%s: cannot reopen (%s)", path, strerror(errno));
    int rc = fsync(fd), e = errno;
    close(fd);
    return rc == 0 ? BTF_OK : btf_fail(err, BTF_ERR_IO, "%s: fsync failed (%s)", path, strerror(e));
}

btf_result btf_fs_commit_file(const char *tmp, const char *path, btf_error *err)
{
    char dir[BTF_FS_PATH_MAX];
    btf_result r = btf__fs_sync_file(tmp, err);
    if (r == BTF_OK && rename(tmp, path) != 0)
        r = btf_fail(err, BTF_ERR_IO, "%s: cannot rename into place (%s)", path, strerror(errno));
    if (r != BTF_OK) {
        unlink(tmp);
        return r;
    }
    btf__fs_dirname(path, dir, sizeof dir);
    return btf_fs_sync_dir(dir, err);
}

/* write(2) of all n bytes, retrying short writes. */
static int btf__fs_write_all(int fd, const void *data, size_t n)
{
    const char *p = data;
    while (n > 0) {
        ssize_t w = write(fd, p, n);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            return 0;
        p += w, n -= (size_t)w;
    }
    return 1;
}

btf_result btf_fs_write_atomic(const char *path, const void *data, size_t n, btf_error *err)
{
    char tmp[BTF_FS_PATH_MAX + 32];
    btf_result r = btf_fs_temp_name(path, tmp, sizeof tmp, err);
    if (r != BTF_OK)
        return r;
    int fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0)
        return btf_fail(err, BTF_ERR_IO, "%s: cannot create (%s)", tmp, strerror(errno));
    int ok = btf__fs_write_all(fd, data, n), e = errno;
    ok = ok && fsync(fd) == 0;
    e = ok ? 0 : (e ? e : errno);
    ok = close(fd) == 0 && ok;
    if (!ok) {
        unlink(tmp);
        return btf_fail(err, BTF_ERR_IO, "%s: write failed (%s)", path, strerror(e ? e : errno));
    }
    if (rename(tmp, path) != 0) {
        e = errno;
        unlink(tmp);
        return btf_fail(err, BTF_ERR_IO, "%s: cannot rename into place (%s)", path, strerror(e));
    }
    char dir[BTF_FS_PATH_MAX];
    btf__fs_dirname(path, dir, sizeof dir);
    return btf_fs_sync_dir(dir, err);
}

static int btf__fs_rm_one(const char *p, const struct stat *st, int flag, struct FTW *f)
{
    (void)st, (void)f;
    return (flag == FTW_DP ? rmdir(p) : unlink(p)) == 0 || errno == ENOENT ? 0 : -1;
}

btf_result btf_fs_rmtree(const char *path, btf_error *err)
{
    struct stat st;
    if (lstat(path, &st) != 0)
        return errno == ENOENT ? BTF_OK : btf_fail(err, BTF_ERR_IO, "%s: %s", path, strerror(errno));
    if (!S_ISDIR(st.st_mode))
        return unlink(path) == 0 ? BTF_OK : btf_fail(err, BTF_ERR_IO, "%s: cannot remove (%s)", path, strerror(errno));
    if (nftw(path, btf__fs_rm_one, 16, FTW_DEPTH | FTW_PHYS) != 0)
        return btf_fail(err, BTF_ERR_IO, "%s: cannot remove the tree (%s)", path, strerror(errno));
    return BTF_OK;
}

int btf_fs_all_entries(const char *dir, btf_fs_entry_fn ok, void *ctx)
{
    char path[2 * BTF_FS_PATH_MAX + 8];
    DIR *d = opendir(dir);
    int all = d != NULL;
    for (struct dirent *e; all && (e = readdir(d));) {
        struct stat st;
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
            continue;
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        all = lstat(path, &st) == 0 && ok(e->d_name, &st, ctx);
    }
    if (d)
        closedir(d);
    return all;
}

static int btf__fs_no_entry(const char *name, const struct stat *st, void *ctx)
{
    (void)name, (void)st, (void)ctx;
    return 0;
}

/* 1 when dir is an empty directory. */
static int btf__fs_is_empty_dir(const char *dir)
{
    return btf_fs_all_entries(dir, btf__fs_no_entry, NULL);
}

/* Removes the leftovers "OUT.tmp-PID[-SUFFIX]" of writers that are no longer running. */
static void btf__fs_clean_stale(const char *out, btf_fs_owned_fn owned, void *ctx)
{
    char dir[BTF_FS_PATH_MAX], path[2 * BTF_FS_PATH_MAX + 8];
    btf__fs_dirname(out, dir, sizeof dir);
    const char *base = strrchr(out, '/') ? strrchr(out, '/') + 1 : out;
    size_t bl = strlen(base);
    DIR *d = opendir(dir);
    for (struct dirent *e; d && (e = readdir(d));) {
        char *end = NULL;
        if (strncmp(e->d_name, base, bl) || strncmp(e->d_name + bl, ".tmp-", 5))
            continue;
        long pid = strtol(e->d_name + bl + 5, &end, 10);
        if (!end || (*end && *end != '-') || pid <= 0 || pid == (long)getpid() || kill((pid_t)pid, 0) == 0 || errno != ESRCH)
            continue;
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        if (btf__fs_is_empty_dir(path) || (owned && owned(path, ctx)))
            btf_fs_rmtree(path, NULL);
    }
    if (d)
        closedir(d);
}

btf_result btf_fs_temp_dir(const char *out, char *buf, size_t n, btf_fs_owned_fn owned, void *ctx, btf_error *err)
{
    btf_result r = btf_fs_temp_name(out, buf, n, err);
    if (r != BTF_OK)
        return r;
    btf__fs_clean_stale(out, owned, ctx);
    struct stat st;
    if (lstat(buf, &st) == 0 && S_ISDIR(st.st_mode) && (btf__fs_is_empty_dir(buf) || (owned && owned(buf, ctx))))
        btf_fs_rmtree(buf, NULL); /* this pid's own leftover */
    if (mkdir(buf, 0755) != 0)
        return btf_fail(err, BTF_ERR_IO, "%s: cannot create (%s)", buf, strerror(errno));
    return BTF_OK;
}

/* Swaps two paths atomically; 0 with errno EINVAL/ENOSYS where unsupported. */
static int btf__fs_exchange(const char *a, const char *b)
{
#ifdef RENAME_EXCHANGE
    return renameat2(AT_FDCWD, a, AT_FDCWD, b, RENAME_EXCHANGE) == 0;
#else
    (void)a, (void)b;
    errno = ENOSYS;
    return 0;
#endif
}

/* Two-rename fallback: out -> OUT.old-PID, tmp -> out, then the old tree goes. */
static btf_result btf__fs_replace_by_rename(const char *tmp, const char *out, btf_error *err)
{
    char old[BTF_FS_PATH_MAX + 32];
    snprintf(old, sizeof old, "%s.old-%ld", out, (long)getpid());
    if (rename(out, old) != 0)
        return btf_fail(err, BTF_ERR_IO, "%s: cannot move aside (%s)", out, strerror(errno));
    if (rename(tmp, out) != 0) {
        int e = errno;
        rename(old, out);
        return btf_fail(err, BTF_ERR_IO, "%s: cannot rename into place (%s)", out, strerror(e));
    }
    return btf_fs_rmtree(old, err);
}

btf_result btf_fs_replaceable(const char *out, btf_fs_owned_fn owned, void *ctx, btf_error *err)
{
    struct stat st;
    if (lstat(out, &st) != 0)
        return BTF_OK;
    if (!S_ISDIR(st.st_mode))
        return btf_fail(err, BTF_ERR_IO, "%s: exists and is not a directory; not replaced", out);
    if (!btf__fs_is_empty_dir(out) && !(owned && owned(out, ctx)))
        return btf_fail(err, BTF_ERR_IO,
                        "%s: exists and holds files this project did not write (not a package of ours); not replaced",
                        out);
    return BTF_OK;
}

btf_result btf_fs_replace_dir(const char *tmp, const char *out, btf_fs_owned_fn owned, void *ctx, btf_error *err)
{
    struct stat st;
    char dir[BTF_FS_PATH_MAX];
    btf__fs_dirname(out, dir, sizeof dir);
    btf_result r = btf_fs_sync_dir(tmp, err);
    if (r != BTF_OK)
        return r;
    if (lstat(out, &st) != 0) {
        if (rename(tmp, out) != 0)
            return btf_fail(err, BTF_ERR_IO, "%s: cannot rename into place (%s)", out, strerror(errno));
        return btf_fs_sync_dir(dir, err);
    }
    r = btf_fs_replaceable(out, owned, ctx, err);
    if (r != BTF_OK)
        return r;
    if (btf__fs_exchange(tmp, out)) /* tmp now holds the old tree */
        r = btf_fs_rmtree(tmp, err);
    else if (errno == EINVAL || errno == ENOSYS || errno == ENOTSUP)
        r = btf__fs_replace_by_rename(tmp, out, err);
    else
        return btf_fail(err, BTF_ERR_IO, "%s: cannot swap into place (%s)", out, strerror(errno));
    return r == BTF_OK ? btf_fs_sync_dir(dir, err) : r;
}
