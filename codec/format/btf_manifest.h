/* btf_manifest.h - the package manifest (doc/package-format.md section 3)
 * as text and as the in-memory btf_package: one parser and one serializer for
 * both versions. Used by the package writer, reader and level builder.
 *
 *     btf_package p = {0};
 *     if (btf_manifest_parse(text, "lib/wool/manifest.json", &p, &err) == BTF_OK) {
 *         char *again = btf_manifest_print(&p, &err);   // same manifest, p.version decides
 *         free(again);
 *     }
 *     btf_manifest_clear(&p);
 */
#ifndef BTF_MANIFEST_H
#define BTF_MANIFEST_H

#include "btf_package.h"

#ifdef __cplusplus
extern "C" {
#endif

#define BTF_MANIFEST_MAX_BYTES ((size_t)64 << 20) /* a larger manifest.json is refused unread */
#define BTF_MANIFEST_MAX_CHUNK_BYTES ((long long)1 << 40) /* "bytes" of one chunk: 0 .. 1 TiB */

/* Fills the header and chunk list of p (no chunk data: n_loaded = 0) from manifest
 * text; path names the file in messages. Every number is range-checked before it is
 * converted. On error p holds what was parsed so far: btf_manifest_clear frees it. */
btf_result btf_manifest_parse(const char *text, const char *path, btf_package *p, btf_error *err);

/* btf_manifest_parse of DIR/manifest.json (read bounded by BTF_MANIFEST_MAX_BYTES);
 * _with reads it through files (btf.h; NULL: the disk). */
btf_result btf_manifest_load(const char *dir, btf_package *p, btf_error *err);
btf_result btf_manifest_load_with(const char *dir, const btf_files *files, btf_package *p, btf_error *err);

/* Manifest text of p (malloc'd) in p->version's layout: version 1 with per-chunk
 * ranges, version 2 with levels and per-component ranges; NULL when out of memory. */
char *btf_manifest_print(const btf_package *p, btf_error *err);

/* Frees what btf_manifest_parse allocated inside p (chunks, ranges, blocks). */
void btf_manifest_clear(btf_package *p);

/* 1 when s is a valid package or file name: 1..BTF_PACKAGE_NAME_MAX-1 of [A-Za-z0-9._-], not "." or "..". */
int btf_manifest_valid_name(const char *s);

/* 1 when dir is a package this project wrote: its manifest says "btf-package"
 * version 1 or 2, and every entry is a regular file that the manifest lists, or
 * manifest.json, or thumbnail.png. For btf_fs_replace_dir (ctx unused). */
int btf_manifest_owns_dir(const char *dir, void *ctx);

/* 1 when every entry of dir is a regular file named as a package writer names
 * its files (manifest.json, thumbnail.png, tex-*, wt-*, and their temporaries):
 * a writer's unfinished temporary directory, safe to remove. */
int btf_manifest_owns_temp(const char *dir, void *ctx);

/* Version 4 (doc/package-format.md section 4.3): 1 when chunk i's texture is a residual
 * over its component's next coarser level (its name ends "-dL.png", L = its level,
 * below the coarsest level), 0 when it holds the level's texels directly. */
int btf_package_chunk_residual(const btf_package *p, int i);

#ifdef __cplusplus
}
#endif
#endif
