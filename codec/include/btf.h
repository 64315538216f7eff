/* btf.h - core of the BTF codec library (libbtfcodec.a).
 *
 * Usage:
 *     btf_dirset d = btf_dirset_ubo2003();
 *     btf *m = NULL;
 *     btf_error err = {0};
 *     if (btf_create(64, 64, &d, &d, BTF_U8, &m, &err) != BTF_OK)
 *         fprintf(stderr, "%s\n", err.msg);
 *     float r = btf_get(m, view, light, x, y, 0);
 *     btf_free(m);
 *
 * A BTF is W x H texels, a light direction set and a view direction set, RGB.
 * Samples are stored either as bytes (as measured images store them) or as
 * float32; either way btf_get() returns byte/255 scale floats (0..1 for
 * in-range data; values are in the images' own, sRGB-encoded, scale: no
 * gamma conversion happens anywhere in the library).
 * Memory layout: [view][light][y][x][c], c fastest, contiguous.
 *
 * Limitations: at most BTF_MAX_RINGS rings and BTF_MAX_DIRS directions per set.
 * The library never prints, exits or aborts on bad input: every fallible call
 * returns a btf_result and, when given a btf_error, a message naming the cause.
 */
#ifndef BTF_H
#define BTF_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum btf_result {
    BTF_OK = 0,
    BTF_ERR_ARG,         /* invalid argument from the caller */
    BTF_ERR_IO,          /* a file could not be opened, read or written */
    BTF_ERR_FORMAT,      /* input is not in the expected format */
    BTF_ERR_RANGE,       /* a size, count or value is outside what is allowed */
    BTF_ERR_NOMEM,       /* an allocation failed */
    BTF_ERR_UNSUPPORTED, /* a valid input the library does not implement */
    BTF_ERR_NUMERIC,     /* NaN/Inf in input or a numerical failure */
    BTF_ERR_MISSING      /* an expected file or entry is absent */
} btf_result;

/* Short constant description of a result code. */
const char *btf_result_string(btf_result r);

/* Caller-owned message buffer filled by failing calls; lives as long as the caller wants. */
typedef struct btf_error {
    char msg[512];
} btf_error;

/* ---------------------------------------------------------------- files */

/* Where a reader of a directory (a package, btf_package_read_with) gets its files,
 * as cgltf's cgltf_file_options: zero is the disk; the callbacks serve the files
 * from elsewhere (memory, an archive). The reader asks for "DIR/NAME", the path its
 * messages name. Plain value, the caller's; user must outlive the read. */
typedef struct btf_files {
    /* Whole file into *out, a new NUL-terminated malloc'd buffer the reader frees,
     * *size its length. A file over max_bytes is BTF_ERR_RANGE before anything is
     * allocated, a missing one BTF_ERR_MISSING; *out NULL on error. NULL: the disk. */
    btf_result (*read)(void *user, const char *path, size_t max_bytes, char **out, size_t *size, btf_error *err);
    /* Size of the file in bytes, -1 when it is missing. NULL: the disk. */
    long long (*size)(void *user, const char *path);
    void *user; /* passed to both */
} btf_files;

/* ---------------------------------------------------------------- directions */

#define BTF_MAX_RINGS 32
#define BTF_MAX_DIRS 2048

/* One ring of directions at fixed theta; value type, owned by its btf_dirset. */
typedef struct btf_ring {
    float theta_deg;      /* polar angle from the normal, degrees, 0..90 */
    int count;            /* directions on the ring, >= 1 */
    float phi_offset_deg; /* phi of the first direction; then phi += 360/count */
} btf_ring;

/* Most directions of an explicit list set (the GPU tables hold 1020 in all). */
#define BTF_MAX_LIST_DIRS 1024

/* A direction set: rings in ascending theta (the fast path), or an explicit list
 * (n_rings == 0). Plain value, no heap, copy freely (about 8.5 KB).
 * Ring sets: canonical order ring by ring (ascending theta), then ascending phi
 * index; ring_start[r] is the canonical index of ring r's first direction.
 * List sets: index order as listed; list[i] = {theta, phi} in degrees (theta
 * 0..90, phi wrapped to 0..360); interpolated over the convex hull of the
 * directions and their mirror images below the horizon (btf_dirtab.h). */
typedef struct btf_dirset {
    int n_rings;
    int n_dirs;
    btf_ring rings[BTF_MAX_RINGS];
    int ring_start[BTF_MAX_RINGS];
    float list[BTF_MAX_LIST_DIRS][2];
} btf_dirset;

/* 1 for an explicit list set, 0 for a ring set. */
static inline int btf_dirset_is_list(const btf_dirset *d) { return d->n_rings == 0 && d->n_dirs > 0; }

/* Builds a set from a ring table; checks ascending theta, counts, limits. */
btf_result btf_dirset_make(const btf_ring *rings, int n_rings, btf_dirset *out, btf_error *err);
/* UBO2003: theta 0..75 step 15, counts 1,6,12,18,20,24, offsets 0 (81 dirs). */
btf_dirset btf_dirset_ubo2003(void);
/* UBO2014 dome: 151 directions on 10 rings (doc/input-formats.md section 2.8). */
btf_dirset btf_dirset_dome151(void);
/* Builds a list set from n {theta, phi} pairs in degrees (index order kept);
 * checks 3 <= n <= BTF_MAX_LIST_DIRS, theta in 0..90, no two directions within
 * 0.01 degrees, and that the directions surround the normal (they triangulate). */
btf_result btf_dirset_make_list(const float (*dirs)[2], int n, btf_dirset *out, btf_error *err);
/* Reads {"rings":[{"theta":deg,"count":n,"phi_offset":deg},...]} or
 * {"directions":[{"theta":deg,"phi":deg},...]} (cJSON). */
btf_result btf_dirset_load_json(const char *path, btf_dirset *out, btf_error *err);
/* Same from JSON text of len bytes; name labels error messages (e.g. the file name). */
btf_result btf_dirset_parse_json(const char *text, size_t len, const char *name, btf_dirset *out, btf_error *err);
/* theta/phi in degrees of canonical direction i (0 <= i < n_dirs). */
void btf_dirset_angles(const btf_dirset *d, int i, float *theta_deg, float *phi_deg);
/* Unit vector (x, y, z) of direction i: x = sin t cos p, y = sin t sin p, z = cos t. */
void btf_dirset_vector(const btf_dirset *d, int i, float v[3]);
/* Canonical index of the direction at (theta, phi) within tol degrees, or -1. */
int btf_dirset_find(const btf_dirset *d, float theta_deg, float phi_deg, float tol_deg);
/* Polar angle of the set's outermost direction, degrees. */
float btf_dirset_max_theta(const btf_dirset *d);
/* 1 if both sets have the same rings (or the same list, in the same order). */
int btf_dirset_equal(const btf_dirset *a, const btf_dirset *b);

/* Angular interpolation result: up to 3 measured directions and weights summing to 1.
 * Unused slots have weight 0 and repeat a valid index. Value type. */
typedef struct btf_interp {
    int idx[3];
    float w[3];
} btf_interp;

/* The 3 measured directions around (theta, phi) in degrees and their
 * barycentric weights; the CPU reference the shaders match. Never NaN.
 * A list set is triangulated (qhull) on its first query in a thread and the table
 * kept for the next queries on the same list (one per thread); btf_dirtab.h gives
 * the table itself. */
btf_interp btf_dirset_interp(const btf_dirset *d, float theta_deg, float phi_deg);
/* Same for a direction vector in the local frame (z = normal); need not be unit. */
btf_interp btf_dirset_interp_vec(const btf_dirset *d, const float v[3]);

/* ---------------------------------------------------------------- the BTF */

typedef enum btf_storage { BTF_U8 = 1, BTF_F32 = 2 } btf_storage;

/* An in-memory BTF. Created by btf_create or a loader, owned by the caller,
 * released with btf_free. data holds n_views*n_lights*height*width*3 samples. */
typedef struct btf {
    int width, height;
    btf_dirset lights, views;
    btf_storage storage;
    void *data;   /* malloc'd: uint8_t* for BTF_U8, float* for BTF_F32 */
    size_t count; /* number of samples (not bytes) */
} btf;

/* Largest accepted sample count (guards allocations from file headers): 2^34. */
#define BTF_MAX_SAMPLES ((size_t)1 << 34)
#define BTF_MAX_SIDE 16384

/* Allocates a zero-filled BTF. */
btf_result btf_create(int width, int height, const btf_dirset *lights, const btf_dirset *views,
                      btf_storage storage, btf **out, btf_error *err);
void btf_free(btf *b);

/* Index of sample (view, light, x, y, c) in data. */
static inline size_t btf_index(const btf *b, int view, int light, int x, int y, int c)
{
    return ((((size_t)view * (size_t)b->lights.n_dirs + (size_t)light) * (size_t)b->height + (size_t)y) *
                (size_t)b->width + (size_t)x) * 3u + (size_t)c;
}
/* Samples per (view, light) image: width*height*3. */
static inline size_t btf_image_samples(const btf *b) { return (size_t)b->width * (size_t)b->height * 3u; }

/* Sample on the byte/255 scale. */
float btf_get(const btf *b, int view, int light, int x, int y, int c);
/* Stores v (byte/255 scale); BTF_U8 rounds and clamps to 0..255 (btf_to_u8). */
void btf_set(btf *b, int view, int light, int x, int y, int c, float v);
/* A byte/255-scale value as the byte an 8-bit image stores: rounded half up,
 * clamped to 0..255, NaN as 0. Every 8-bit writer of the library uses it. */
static inline uint8_t btf_to_u8(float v)
{
    float q = v * 255.0f + 0.5f;
    return !(q > 0.0f) ? 0 : q >= 255.0f ? 255 : (uint8_t)q;
}
/* Copies one (view, light) image into dst (width*height*3 floats, byte/255 scale). */
void btf_get_image(const btf *b, int view, int light, float *dst);
/* Copies n texels (row-major, from texel index `first` = y*width + x) of one
 * (view, light) image into dst (n*3 floats, byte/255 scale). */
void btf_get_texels(const btf *b, int view, int light, size_t first, size_t n, float *dst);

/* Spatial box downsampling by an integer factor (width and height must divide). */
btf_result btf_downsample(const btf *src, int factor, btf **out, btf_error *err);
/* The w x h window of src at (x0, y0), a new BTF of the same directions and storage. */
btf_result btf_crop(const btf *src, int x0, int y0, int w, int h, btf **out, btf_error *err);
/* Checks every sample is finite (BTF_F32); BTF_ERR_NUMERIC names the first bad one. */
btf_result btf_check_finite(const btf *b, btf_error *err);

#ifdef __cplusplus
}
#endif
#endif
