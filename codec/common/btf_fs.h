/* btf_fs.h - the file helpers every writer and reader of the project uses, one copy each.
 *
 *     size_t n;
 *     char *text;
 *     if (btf_fs_read("lib/wool/manifest.json", 1 << 20, &text, &n, &err) != BTF_OK) ...; // NUL-terminated
 *     btf_fs_write_atomic("out/notes.txt", text, n, &err);  // temp + fsync + rename + fsync dir
 *     free(text);
 *
 *     char tmp[BTF_FS_PATH_MAX];
 *     btf_fs_temp_dir("lib/wool", tmp, sizeof tmp, &err);   // "lib/wool.tmp-PID", made empty
 *     ... write files into tmp ...
 *     btf_fs_replace_dir(tmp, "lib/wool", is_package, NULL, &err); // never a moment without one
 *
 *     btf_fs_mem_file f[3] = {{"manifest.json", text, n}, {"tex-00.png", png, png_n}, {"wt-00.bin", wt, wt_n}};
 *     btf_fs_mem m = {f, 3};
 *     btf_files files = btf_fs_mem_files(&m);               // a package's first chunk in memory
 *     btf_package_read_with("mem", 1, &files, &p, &err);    // reads "mem/manifest.json", ...
 *
 * Writers name temporary files and directories "NAME.tmp-PID[-N]" in the same
 * directory as NAME; readers of libraries skip such names.
 */
#ifndef BTF_FS_H
#define BTF_FS_H

#include <stddef.h>
#include <sys/stat.h>

#include "btf.h"

#ifdef __cplusplus
extern "C" {
#endif

#define BTF_FS_PATH_MAX 4096

/* Whole file into *out, a new NUL-terminated buffer (free it); *size (optional)
 * gets its length. A file larger than max_bytes is refused before anything is
 * allocated (BTF_ERR_RANGE); a missing one is BTF_ERR_MISSING. *out is NULL on error. */
btf_result btf_fs_read(const char *path, size_t max_bytes, char **out, size_t *size, btf_error *err);

/* Size of a regular file in bytes, or -1 when it is missing or not a regular file. */
long long btf_fs_size(const char *path);

/* btf_fs_read and btf_fs_size through a reader's btf_files (btf.h): files NULL, or
 * a NULL callback, is the disk. */
btf_result btf_fs_read_with(const btf_files *files, const char *path, size_t max_bytes, char **out, size_t *size,
                            btf_error *err);
long long btf_fs_size_with(const btf_files *files, const char *path);

/* One file held in memory: the caller's, as are its name and bytes, for as long as
 * the reads that are served it. */
typedef struct btf_fs_mem_file {
    const char *name; /* "manifest.json", "tex-00.png", ... */
    const void *data;
    size_t size;
} btf_fs_mem_file;
/* Files held in memory, served to a reader by btf_fs_mem_files: a path is looked up
 * by its last element (a package is one flat directory). The caller's, for as long
 * as the reads. */
typedef struct btf_fs_mem {
    const btf_fs_mem_file *file; /* n of them */
    int n;
} btf_fs_mem;

/* A btf_files that serves m (read: a malloc'd copy, refused as btf_fs_read refuses:
 * a missing name BTF_ERR_MISSING, one over max_bytes BTF_ERR_RANGE). */
btf_files btf_fs_mem_files(const btf_fs_mem *m);

/* Where a writer hands each file it makes instead of writing it (the package
 * writer's btf_package_channel.sink): name is the file's name in its directory, the
 * callee copies what it keeps. */
typedef btf_result (*btf_fs_sink_fn)(void *user, const char *name, const void *data, size_t n, btf_error *err);

/* Files collected in memory, each a copy it owns (name and bytes) until
 * btf_fs_memdir_free; mem serves them to a reader through btf_fs_mem_files(&d.mem)
 * and stays valid until the next put. Zero-initialised before the first put. */
typedef struct btf_fs_memdir {
    btf_fs_mem mem;
    int cap;
} btf_fs_memdir;

/* A btf_fs_sink_fn over a btf_fs_memdir (user): a copy of the file, replacing one of
 * the same name. */
btf_result btf_fs_memdir_put(void *user, const char *name, const void *data, size_t n, btf_error *err);
void btf_fs_memdir_free(btf_fs_memdir *d);

/* Writes n bytes to path atomically: a temporary in the same directory, fsync,
 * rename over path, fsync of the directory. On failure path is untouched and the
 * temporary removed. */
btf_result btf_fs_write_atomic(const char *path, const void *data, size_t n, btf_error *err);

/* Renames the temporary file tmp over path (same directory), with fsync of tmp
 * before and of the directory after; removes tmp on failure. For writers that
 * produce the file through another library (images). */
btf_result btf_fs_commit_file(const char *tmp, const char *path, btf_error *err);

/* "PATH.tmp-PID" into buf; for files written by another library before btf_fs_commit_file. */
btf_result btf_fs_temp_name(const char *path, char *buf, size_t n, btf_error *err);

/* fsync of a directory (its entries); BTF_OK where the file system cannot. */
btf_result btf_fs_sync_dir(const char *dir, btf_error *err);

/* Creates the empty directory "OUT.tmp-PID" for a writer of OUT. A leftover of
 * this pid is removed first when every entry passes owned(); leftovers of dead
 * pids whose entries pass owned() are removed too (a killed writer's). */
typedef int (*btf_fs_owned_fn)(const char *dir, void *ctx);
btf_result btf_fs_temp_dir(const char *out, char *buf, size_t n, btf_fs_owned_fn owned, void *ctx, btf_error *err);

/* Puts the directory tmp in place of out. When out exists it must be an empty
 * directory or pass owned(out, ctx) (a directory this project wrote); anything
 * else is refused and left alone. The swap is atomic (renameat2 RENAME_EXCHANGE;
 * where the file system lacks it, two renames), then the old tree is removed. */
btf_result btf_fs_replace_dir(const char *tmp, const char *out, btf_fs_owned_fn owned, void *ctx, btf_error *err);

/* BTF_OK when btf_fs_replace_dir could put a directory in place of out: out is
 * absent, an empty directory, or a directory that passes owned(out, ctx). */
btf_result btf_fs_replaceable(const char *out, btf_fs_owned_fn owned, void *ctx, btf_error *err);

/* 1 when dir can be read and every entry but . and .. passes ok(name, st, ctx)
 * (st from lstat: links are not followed); the walk stops at the first that fails. */
typedef int (*btf_fs_entry_fn)(const char *name, const struct stat *st, void *ctx);
int btf_fs_all_entries(const char *dir, btf_fs_entry_fn ok, void *ctx);

/* Removes a tree (files, links and folders below path, then path) without
 * following links; BTF_OK when path does not exist. */
btf_result btf_fs_rmtree(const char *path, btf_error *err);

#ifdef __cplusplus
}
#endif
#endif
