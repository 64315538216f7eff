/* btfd_library.h - the material library: an index of package directories.
 *
 * Usage:
 *     btfd_library *lib = NULL;
 *     btf_error err = {0};
 *     if (btfd_library_open("/srv/materials", &lib, &err) != BTF_OK) ...
 *     btfd_library_scan(lib, log_fn, NULL);      // again later to pick up changes
 *     btfd_material *m = btfd_library_find(lib, "wool");
 *     if (m) { btfd_material_ref(m); ... btfd_material_unref(m); }
 *     btfd_library_free(lib);
 *
 * A package is a subdirectory holding manifest.json ("format": "btf-package",
 * "version": 1 or 2, "chunks": [{"id","files","bytes","rmse","lab"},...]) and the
 * files its chunks name. Directories whose name is not a valid material name
 * (btfd_name_valid: this excludes hidden ones), contains ".tmp-" or ".old-"
 * (being written or replaced, see doc/package-format.md), or that lack
 * manifest.json are skipped. Every file is mmapped read-only once,
 * when the package is loaded; all connections share the mapping.
 *
 * Materials are reference counted: a rescan that drops or replaces a package
 * only releases the library's reference, so a connection still streaming it
 * keeps a valid mapping until it lets go. Not thread-safe (btfd is one thread).
 * Limitations: a file truncated in place while mapped raises SIGBUS; packages
 * must be replaced by writing a new directory and renaming it (what the
 * compressor does), never edited in place.
 */
#ifndef BTFD_LIBRARY_H
#define BTFD_LIBRARY_H

#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "btf.h"
#include "btf_lod.h"

#define BTFD_MANIFEST_MAX (4u << 20)        /* largest manifest.json, bytes */
#define BTFD_FILE_MAX 0x7fffffffu           /* largest package file (offsets are u32) */
#define BTFD_FILES_PER_CHUNK 64             /* most files one chunk may name */
#define BTFD_MATERIALS_MAX 4096             /* most packages in one library */
#define BTFD_THUMB_MAX (16u << 20)          /* largest thumbnail.png served */

/* One package file, mapped read-only; owned by its btfd_material. */
typedef struct btfd_file {
    char *name;          /* file name inside the package (malloc'd) */
    const uint8_t *data; /* mmapped contents, NULL when size is 0 */
    size_t size;
} btfd_file;

/* One chunk of a package, in importance order; owned by its btfd_material. */
typedef struct btfd_chunk {
    char *id;         /* manifest's chunk id (malloc'd) */
    int n_files;
    btfd_file *files; /* malloc'd array of n_files */
    uint64_t bytes;   /* actual bytes: sum of the files' sizes */
    double error;     /* error once this chunk has arrived (see metric), NaN if unknown */
} btfd_chunk;

/* A loaded package. Reference counted; freed when the last reference goes. */
typedef struct btfd_material {
    int refs;
    char *name;            /* directory name = the name clients use (malloc'd) */
    char *manifest;        /* manifest.json text, verbatim (malloc'd, NUL-terminated) */
    size_t manifest_len;
    char etag[17];         /* 64-bit FNV-1a of the manifest text, hex */
    const char *metric;    /* "lab" or "rmse": which manifest error the chunks' error holds */
    int n_chunks;
    btfd_chunk *chunks;    /* malloc'd array of n_chunks */
    uint64_t total_bytes;
    const uint8_t *thumb;  /* mmapped thumbnail.png or NULL */
    size_t thumb_size;
    char *summary;         /* JSON object text for the list (malloc'd) */
    btf_package *lod;      /* packages with levels: what btf_lod_select reads of the manifest
                              (version, width, levels, per chunk component, level, contrib, bytes;
                              malloc'd), else NULL: a footprint budget then allows every chunk */
    dev_t dev;             /* identity of manifest.json when loaded: a rescan */
    ino_t ino;             /* reloads the package when any of these change */
    int64_t mtime_ns;
    off_t msize;
} btfd_material;

/* The index. Created by btfd_library_open, freed by btfd_library_free. */
typedef struct btfd_library {
    char *dir;               /* library directory (malloc'd) */
    int n;
    btfd_material **items;   /* malloc'd, sorted by name; one reference each */
    char *list_json;         /* JSON array of the summaries (malloc'd) */
    uint64_t generation;     /* incremented when the set of packages changes */
} btfd_library;

/* The prefix of m's chunks a view needs where one repeat of the material spans `pixels`
 * device pixels, at visibility threshold (doc/package-format.md section 7.4:
 * btf_lod_select at width / pixels texels per pixel); every chunk for packages without
 * levels, none when pixels <= 0 (off screen). */
int btfd_material_lod_limit(const btfd_material *m, double pixels, double threshold);

/* Log sink for packages skipped during a scan (the library never prints). */
typedef void (*btfd_log_fn)(void *ud, const char *msg);

btf_result btfd_library_open(const char *dir, btfd_library **out, btf_error *err);
/* Re-reads the directory: new packages appear, removed ones disappear,
 * changed ones are reloaded, unchanged ones are kept as they are. */
btf_result btfd_library_scan(btfd_library *lib, btfd_log_fn log, void *ud);
void btfd_library_free(btfd_library *lib);
/* The list as GET /materials answers it and `btfd --publish` writes it to materials.json:
 * {"generation":G,"materials":[SUMMARY,...]} and a newline (malloc'd; NULL: out of memory). */
char *btfd_library_list_body(const btfd_library *lib);
/* Looks a name up in the index (exact match); NULL when absent. No reference taken. */
btfd_material *btfd_library_find(const btfd_library *lib, const char *name);

/* Loads one package directory (path) under the given name. */
btf_result btfd_material_load(const char *path, const char *name, btfd_material **out, btf_error *err);
void btfd_material_ref(btfd_material *m);
/* The file of m called name (any chunk), or NULL; names are compared, never opened. */
const btfd_file *btfd_material_file(const btfd_material *m, const char *name);
/* 64-bit FNV-1a: the etags of manifests and of the list. */
uint64_t btfd_hash64(const void *p, size_t n);
void btfd_material_unref(btfd_material *m);

#endif
