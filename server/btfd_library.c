/* btfd_library.c - the material library index; see btfd_library.h. */
#include "btfd_library.h"

#include <cJSON.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include "btfd_request.h"
#include "btf_common.h"

/* Manifest keys copied verbatim into the list summary when present. */
static const char *const summary_keys[] = {"version", "levels", "width", "height", "k", "components", "bits",
                                           "lights", "views", "sampling", "source"};

static char *dup_str(const char *s)
{
    size_t n = strlen(s) + 1;
    char *d = malloc(n);
    if (d)
        memcpy(d, s, n);
    return d;
}

uint64_t btfd_hash64(const void *p, size_t n)
{
    const uint8_t *b = p;
    uint64_t h = 1469598103934665603ull;
    for (size_t i = 0; i < n; i++) {
        h ^= b[i];
        h *= 1099511628211ull;
    }
    return h;
}

/* Maps path read-only; regular files up to max bytes. size 0 gives data NULL. */
static btf_result map_file(const char *path, size_t max, const uint8_t **data, size_t *size,
                           btf_error *err)
{
    *data = NULL;
    *size = 0;
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return btf_fail(err, errno == ENOENT ? BTF_ERR_MISSING : BTF_ERR_IO, "%s: %s", path,
                        strerror(errno));
    struct stat st;
    btf_result r = BTF_OK;
    if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode))
        r = btf_fail(err, BTF_ERR_FORMAT, "%s: not a regular file", path);
    else if ((uint64_t)st.st_size > max)
        r = btf_fail(err, BTF_ERR_RANGE, "%s: %lld bytes (at most %zu)", path, (long long)st.st_size, max);
    else if (st.st_size > 0) {
        void *p = mmap(NULL, (size_t)st.st_size, PROT_READ, MAP_SHARED, fd, 0);
        if (p == MAP_FAILED)
            r = btf_fail(err, BTF_ERR_IO, "%s: mmap: %s", path, strerror(errno));
        else {
            *data = p;
            *size = (size_t)st.st_size;
        }
    }
    close(fd);
    return r;
}

static void unmap(const uint8_t *data, size_t size)
{
    if (data && size)
        munmap((void *)data, size);
}

static void chunk_clear(btfd_chunk *c)
{
    for (int i = 0; i < c->n_files; i++) {
        free(c->files[i].name);
        unmap(c->files[i].data, c->files[i].size);
    }
    free(c->files);
    free(c->id);
}

static void material_destroy(btfd_material *m)
{
    if (!m)
        return;
    for (int i = 0; i < m->n_chunks; i++)
        chunk_clear(&m->chunks[i]);
    free(m->chunks);
    if (m->lod)
        free(m->lod->chunk);
    free(m->lod);
    unmap(m->thumb, m->thumb_size);
    free(m->summary);
    free(m->manifest);
    free(m->name);
    free(m);
}

void btfd_material_ref(btfd_material *m)
{
    if (m)
        m->refs++;
}

void btfd_material_unref(btfd_material *m)
{
    if (m && --m->refs <= 0)
        material_destroy(m);
}

/* Reads manifest.json of dir into m->manifest (bounded) and records its identity. */
static btf_result read_manifest(const char *dir, btfd_material *m, btf_error *err)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/manifest.json", dir);
    FILE *f = fopen(path, "rb");
    if (!f)
        return btf_fail(err, errno == ENOENT ? BTF_ERR_MISSING : BTF_ERR_IO, "%s: %s", path,
                        strerror(errno));
    struct stat st;
    btf_result r = BTF_OK;
    if (fstat(fileno(f), &st) != 0 || !S_ISREG(st.st_mode))
        r = btf_fail(err, BTF_ERR_FORMAT, "%s: not a regular file", path);
    else if ((uint64_t)st.st_size > BTFD_MANIFEST_MAX || st.st_size == 0)
        r = btf_fail(err, BTF_ERR_RANGE, "%s: %lld bytes (1..%u allowed)", path,
                     (long long)st.st_size, BTFD_MANIFEST_MAX);
    else if (!(m->manifest = malloc((size_t)st.st_size + 1)))
        r = btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
    else if (fread(m->manifest, 1, (size_t)st.st_size, f) != (size_t)st.st_size)
        r = btf_fail(err, BTF_ERR_IO, "%s: short read", path);
    if (r == BTF_OK) {
        m->manifest_len = (size_t)st.st_size;
        m->manifest[m->manifest_len] = 0;
        m->dev = st.st_dev;
        m->ino = st.st_ino;
        m->mtime_ns = (int64_t)st.st_mtim.tv_sec * 1000000000 + st.st_mtim.tv_nsec;
        m->msize = st.st_size;
        snprintf(m->etag, sizeof m->etag, "%016llx",
                 (unsigned long long)btfd_hash64(m->manifest, m->manifest_len));
    }
    fclose(f);
    return r;
}

/* 1 if every chunk in the array has a finite number >= 0 under key. */
static int all_have(const cJSON *chunks, const char *key)
{
    const cJSON *c;
    cJSON_ArrayForEach(c, chunks) {
        const cJSON *v = cJSON_GetObjectItemCaseSensitive(c, key);
        if (!cJSON_IsNumber(v) || !isfinite(v->valuedouble) || v->valuedouble < 0)
            return 0;
    }
    return 1;
}

/* Fills chunk ci from its manifest object: id, files (mapped), error. */
static btf_result load_chunk(const char *dir, const cJSON *jc, int ci, const char *metric,
                             btfd_chunk *c, btf_error *err)
{
    const cJSON *id = cJSON_GetObjectItemCaseSensitive(jc, "id");
    const cJSON *files = cJSON_GetObjectItemCaseSensitive(jc, "files");
    int nf = cJSON_GetArraySize(files);
    if (!cJSON_IsObject(jc) || !cJSON_IsArray(files) || nf < 1 || nf > BTFD_FILES_PER_CHUNK)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d needs \"files\" (1..%d names)", dir, ci,
                        BTFD_FILES_PER_CHUNK);
    char idbuf[32];
    snprintf(idbuf, sizeof idbuf, "%d", ci);
    c->id = dup_str(cJSON_IsString(id) ? id->valuestring : idbuf);
    c->files = calloc((size_t)nf, sizeof *c->files);
    if (!c->id || !c->files)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", dir);
    const cJSON *v = metric ? cJSON_GetObjectItemCaseSensitive(jc, metric) : NULL;
    c->error = v ? v->valuedouble : NAN;
    const cJSON *f;
    cJSON_ArrayForEach(f, files) {
        if (!cJSON_IsString(f) || !btfd_name_valid(f->valuestring, strlen(f->valuestring)))
            return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d names an invalid file", dir, ci);
        btfd_file *bf = &c->files[c->n_files++];
        if (!(bf->name = dup_str(f->valuestring)))
            return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", dir);
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", dir, bf->name);
        btf_result r = map_file(path, BTFD_FILE_MAX, &bf->data, &bf->size, err);
        if (r != BTF_OK)
            return r;
        c->bytes += bf->size;
    }
    return BTF_OK;
}

/* Builds m->summary: the list entry of this material. */
static btf_result make_summary(const cJSON *root, btfd_material *m, btf_error *err)
{
    cJSON *s = cJSON_CreateObject();
    const cJSON *title = cJSON_GetObjectItemCaseSensitive(root, "name");
    cJSON_AddStringToObject(s, "name", m->name);
    cJSON_AddStringToObject(s, "title", cJSON_IsString(title) ? title->valuestring : m->name);
    cJSON_AddNumberToObject(s, "chunks", m->n_chunks);
    cJSON_AddNumberToObject(s, "bytes", (double)m->total_bytes);
    cJSON_AddStringToObject(s, "etag", m->etag);
    cJSON_AddStringToObject(s, "metric", m->metric ? m->metric : "none");
    double e = m->chunks[m->n_chunks - 1].error;
    if (isfinite(e))
        cJSON_AddNumberToObject(s, "error", e);
    else
        cJSON_AddNullToObject(s, "error");
    for (size_t i = 0; i < sizeof summary_keys / sizeof summary_keys[0]; i++) {
        const cJSON *v = cJSON_GetObjectItemCaseSensitive(root, summary_keys[i]);
        if (v)
            cJSON_AddItemToObject(s, summary_keys[i], cJSON_Duplicate(v, 1));
    }
    char base[BTFD_NAME_MAX + 48];
    snprintf(base, sizeof base, "/materials/%s/%s/", m->name, m->etag);
    cJSON_AddStringToObject(s, "files", base); /* immutable package files: base + file name */
    if (m->thumb) {
        char url[BTFD_NAME_MAX + 40];
        snprintf(url, sizeof url, "/materials/%s/thumbnail.png", m->name);
        cJSON_AddStringToObject(s, "thumbnail", url);
    } else {
        cJSON_AddNullToObject(s, "thumbnail");
    }
    m->summary = cJSON_PrintUnformatted(s);
    cJSON_Delete(s);
    return m->summary ? BTF_OK : btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", m->name);
}

/* Integer JSON number in [lo, hi] (lo >= 0), or -1. */
static int int_in(const cJSON *v, int lo, int hi)
{
    int64_t x;
    return btfd_json_int(v, lo, hi, &x) ? (int)x : -1;
}

/* m->lod for a package with levels (versions 2 and 4); left NULL when the manifest's
 * width, levels, components or levels of its chunks are missing or out of range. */
static void load_lod(const cJSON *root, const cJSON *chunks, btfd_material *m)
{
    int version = int_in(cJSON_GetObjectItemCaseSensitive(root, "version"), 1, 4);
    int levels = int_in(cJSON_GetObjectItemCaseSensitive(root, "levels"), 1, 15);
    int width = int_in(cJSON_GetObjectItemCaseSensitive(root, "width"), 1, 1 << 20);
    if ((version != 2 && version != 4) || levels < 1 || width < 1)
        return;
    btf_package *p = calloc(1, sizeof *p);
    btf_chunk_info *ci = calloc((size_t)m->n_chunks, sizeof *ci);
    int i = 0;
    const cJSON *jc;
    cJSON_ArrayForEach(jc, chunks) {
        const cJSON *contrib = cJSON_GetObjectItemCaseSensitive(jc, "contrib");
        if (!ci || (ci[i].component = int_in(cJSON_GetObjectItemCaseSensitive(jc, "component"), 0, 1 << 20)) < 0 ||
            (ci[i].level = int_in(cJSON_GetObjectItemCaseSensitive(jc, "level"), 0, levels - 1)) < 0)
            break;
        ci[i].contrib = cJSON_IsNumber(contrib) && isfinite(contrib->valuedouble) ? contrib->valuedouble : 0.0;
        ci[i].bytes = (long long)m->chunks[i].bytes;
        i++;
    }
    if (!p || i != m->n_chunks) {
        free(ci);
        free(p);
        return;
    }
    p->version = version;
    p->width = width;
    p->n_levels = levels;
    p->n_chunks = m->n_chunks;
    p->chunk = ci;
    m->lod = p;
}

int btfd_material_lod_limit(const btfd_material *m, double pixels, double threshold)
{
    if (!(pixels > 0))
        return 0;
    if (!m->lod)
        return m->n_chunks;
    btf_lod_view v = {btf_lod_footprint(m->lod->width, 1.0, pixels), threshold};
    btf_lod_selection sel;
    btf_lod_select(m->lod, &v, &sel, NULL);
    return sel.limit;
}

/* Validates the parsed manifest and loads every chunk. */
static btf_result load_parsed(const char *dir, const cJSON *root, btfd_material *m, btf_error *err)
{
    const cJSON *fmt = cJSON_GetObjectItemCaseSensitive(root, "format");
    const cJSON *ver = cJSON_GetObjectItemCaseSensitive(root, "version");
    const cJSON *chunks = cJSON_GetObjectItemCaseSensitive(root, "chunks");
    if (!cJSON_IsObject(root) || !cJSON_IsString(fmt) || strcmp(fmt->valuestring, "btf-package"))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: manifest \"format\" is not \"btf-package\"", dir);
    /* Version 2 (spatial levels) keeps the chunk contract: files, bytes, per-chunk
     * errors (`rmse`; no `lab`, so the metric falls back to rmse below). */
    /* Version 3 (wt-JJ.z weights) is version 1 with other weight files: the same contract;
     * version 4 (residual levels) is version 2 with other level files. */
    if (!cJSON_IsNumber(ver) || (ver->valuedouble != 1 && ver->valuedouble != 2 && ver->valuedouble != 3 &&
                                 ver->valuedouble != 4))
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: manifest version is not 1, 2, 3 or 4", dir);
    int n = cJSON_GetArraySize(chunks);
    if (!cJSON_IsArray(chunks) || n < 1 || n > BTFD_CHUNK_MAX)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: manifest needs 1..%d chunks", dir, BTFD_CHUNK_MAX);
    m->metric = all_have(chunks, "lab") ? "lab" : all_have(chunks, "rmse") ? "rmse" : NULL;
    if (!(m->chunks = calloc((size_t)n, sizeof *m->chunks)))
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", dir);
    const cJSON *jc;
    cJSON_ArrayForEach(jc, chunks) {
        btf_result r = load_chunk(dir, jc, m->n_chunks, m->metric, &m->chunks[m->n_chunks], err);
        m->n_chunks++;
        if (r != BTF_OK)
            return r;
        m->total_bytes += m->chunks[m->n_chunks - 1].bytes;
    }
    load_lod(root, chunks, m);
    char path[4096];
    snprintf(path, sizeof path, "%s/thumbnail.png", dir);
    btf_error terr;
    if (map_file(path, BTFD_THUMB_MAX, &m->thumb, &m->thumb_size, &terr) != BTF_OK || !m->thumb) {
        unmap(m->thumb, m->thumb_size);
        m->thumb = NULL;
        m->thumb_size = 0;
    }
    return make_summary(root, m, err);
}

btf_result btfd_material_load(const char *path, const char *name, btfd_material **out, btf_error *err)
{
    *out = NULL;
    btfd_material *m = calloc(1, sizeof *m);
    if (!m || !(m->name = dup_str(name))) {
        free(m);
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
    }
    m->refs = 1;
    btf_result r = read_manifest(path, m, err);
    if (r == BTF_OK) {
        cJSON *root = cJSON_ParseWithLength(m->manifest, m->manifest_len);
        if (!root)
            r = btf_fail(err, BTF_ERR_FORMAT, "%s/manifest.json: malformed JSON", path);
        else
            r = load_parsed(path, root, m, err);
        cJSON_Delete(root);
    }
    if (r != BTF_OK) {
        material_destroy(m);
        return r;
    }
    *out = m;
    return BTF_OK;
}

/* 1 if name marks a package being written or replaced (doc/package-format.md:
 * a name containing ".tmp-" or ".old-" is not a package). */
static int is_temp_name(const char *name)
{
    return strstr(name, ".tmp-") != NULL || strstr(name, ".old-") != NULL;
}

static int cmp_material(const void *a, const void *b)
{
    return strcmp((*(btfd_material *const *)a)->name, (*(btfd_material *const *)b)->name);
}

/* The already loaded material called name whose manifest is unchanged, or NULL. */
static btfd_material *reusable(const btfd_library *lib, const char *name, const struct stat *st)
{
    btfd_material *old = btfd_library_find(lib, name);
    int64_t mt = (int64_t)st->st_mtim.tv_sec * 1000000000 + st->st_mtim.tv_nsec;
    if (old && old->dev == st->st_dev && old->ino == st->st_ino && old->mtime_ns == mt &&
        old->msize == st->st_size)
        return old;
    return NULL;
}

static void logf_(btfd_log_fn log, void *ud, const char *msg)
{
    if (log)
        log(ud, msg);
}

/* Loads or reuses the package called name into items[*n]. */
static void scan_one(btfd_library *lib, const char *name, btfd_material **items, int *n,
                     btfd_log_fn log, void *ud)
{
    char path[4096], mpath[4200];
    snprintf(path, sizeof path, "%s/%s", lib->dir, name);
    snprintf(mpath, sizeof mpath, "%s/manifest.json", path);
    struct stat st;
    if (stat(mpath, &st) != 0)
        return; /* not a package (yet) */
    btfd_material *m = reusable(lib, name, &st);
    if (m) {
        btfd_material_ref(m);
        items[(*n)++] = m;
        return;
    }
    btf_error err = {0};
    if (btfd_material_load(path, name, &m, &err) == BTF_OK)
        items[(*n)++] = m;
    else
        logf_(log, ud, err.msg);
}

/* JSON array of every summary into lib->list_json. */
static btf_result build_list(btfd_library *lib)
{
    size_t len = 3;
    for (int i = 0; i < lib->n; i++)
        len += strlen(lib->items[i]->summary) + 1;
    char *s = malloc(len), *p = s;
    if (!s)
        return BTF_ERR_NOMEM;
    *p++ = '[';
    for (int i = 0; i < lib->n; i++) {
        if (i)
            *p++ = ',';
        size_t k = strlen(lib->items[i]->summary);
        memcpy(p, lib->items[i]->summary, k);
        p += k;
    }
    *p++ = ']';
    *p = 0;
    free(lib->list_json);
    lib->list_json = s;
    return BTF_OK;
}

char *btfd_library_list_body(const btfd_library *lib)
{
    size_t n = strlen(lib->list_json) + 64;
    char *b = malloc(n);
    if (b)
        snprintf(b, n, "{\"generation\":%llu,\"materials\":%s}\n", (unsigned long long)lib->generation,
                 lib->list_json);
    return b;
}

btf_result btfd_library_scan(btfd_library *lib, btfd_log_fn log, void *ud)
{
    DIR *d = opendir(lib->dir);
    if (!d) {
        char msg[600];
        snprintf(msg, sizeof msg, "%s: %s", lib->dir, strerror(errno));
        logf_(log, ud, msg);
        return BTF_ERR_IO;
    }
    btfd_material **items = calloc(BTFD_MATERIALS_MAX, sizeof *items);
    if (!items) {
        closedir(d);
        return BTF_ERR_NOMEM;
    }
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) && n < BTFD_MATERIALS_MAX)
        if (btfd_name_valid(e->d_name, strlen(e->d_name)) && !is_temp_name(e->d_name))
            scan_one(lib, e->d_name, items, &n, log, ud);
    closedir(d);
    qsort(items, (size_t)n, sizeof *items, cmp_material);
    int changed = n != lib->n;
    for (int i = 0; !changed && i < n; i++)
        changed = items[i] != lib->items[i];
    for (int i = 0; i < lib->n; i++)
        btfd_material_unref(lib->items[i]);
    free(lib->items);
    lib->items = items;
    lib->n = n;
    if (changed)
        lib->generation++;
    return build_list(lib);
}

btf_result btfd_library_open(const char *dir, btfd_library **out, btf_error *err)
{
    *out = NULL;
    struct stat st;
    if (!dir || stat(dir, &st) != 0 || !S_ISDIR(st.st_mode))
        return btf_fail(err, BTF_ERR_MISSING, "%s: not a directory", dir ? dir : "(null)");
    btfd_library *lib = calloc(1, sizeof *lib);
    if (!lib || !(lib->dir = dup_str(dir)) || build_list(lib) != BTF_OK) {
        btfd_library_free(lib);
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", dir);
    }
    *out = lib;
    return BTF_OK;
}

void btfd_library_free(btfd_library *lib)
{
    if (!lib)
        return;
    for (int i = 0; i < lib->n; i++)
        btfd_material_unref(lib->items[i]);
    free(lib->items);
    free(lib->list_json);
    free(lib->dir);
    free(lib);
}

btfd_material *btfd_library_find(const btfd_library *lib, const char *name)
{
    int lo = 0, hi = lib->n - 1;
    while (lo <= hi) {
        int mid = (lo + hi) / 2;
        int c = strcmp(name, lib->items[mid]->name);
        if (c == 0)
            return lib->items[mid];
        if (c < 0)
            hi = mid - 1;
        else
            lo = mid + 1;
    }
    return NULL;
}

const btfd_file *btfd_material_file(const btfd_material *m, const char *name)
{
    for (int c = 0; c < m->n_chunks; c++)
        for (int f = 0; f < m->chunks[c].n_files; f++)
            if (!strcmp(m->chunks[c].files[f].name, name))
                return &m->chunks[c].files[f];
    return NULL;
}
