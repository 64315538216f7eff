/* btf_image.c - btf_image.h's functions: each loads the OpenImageIO module
 * (btf_image_module.h) on first use and calls it. Where the module is looked for, first
 * hit wins:
 *   1. $BTF_IMAGE_MODULE, a path to the file (then nowhere else);
 *   2. beside the program, then one folder up (build/bench/, build/fuzz/), then in
 *      ../lib/btfcodec/ from the program (an installed bin/btf);
 *   3. BTF_IMAGE_MODULE_DIR, set at build time (make install's PREFIX/lib/btfcodec).
 * A program that cannot load it gets BTF_ERR_IO naming the places tried, per call. */
#include "btf_image.h"
#include "btf_image_module.h"
#include "btf_avif.h"
#include "btf_common.h"
#include "btf_fs.h"
#include "btf_lossy.h"
#include "btf_png.h"
#include "btf_webp.h"

#include <dlfcn.h>
#include <limits.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#ifndef BTF_IMAGE_MODULE_DIR
#define BTF_IMAGE_MODULE_DIR "/usr/local/lib/btfcodec"
#endif

static const btf_image_host image__host = {
    btf_fail,           btf_fs_read_with, btf_fs_size,     btf_fs_commit_file,
    btf_png_check,      btf_png_check_header, btf_webp_check, btf_webp_encode_grey,
    btf_avif_is_avif,   btf_avif_check,   btf_lossy_codec_of, btf_lossy_decode,
};

/* The loaded module's table, or why there is none: set once (image__once). */
static const btf_image_api *image__api;
static char image__why[1024];
static pthread_once_t image__once = PTHREAD_ONCE_INIT;

/* Opens the module at path: 1 with image__api set, else 0 with the reason appended to image__why. */
static int image__try(const char *path)
{
    void *h = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    const char *why = NULL;
    btf_image_open_fn entry = NULL;
    if (!h)
        why = dlerror();
    else if (!(*(void **)&entry = dlsym(h, BTF_IMAGE_MODULE_ENTRY)))
        why = "no " BTF_IMAGE_MODULE_ENTRY;
    else if (!(image__api = entry(&image__host, BTF_IMAGE_MODULE_ABI)))
        why = "built for another version of this program";
    if (why) {
        size_t used = strlen(image__why);
        snprintf(image__why + used, sizeof image__why - used, "%s%s (%s)", used ? "; " : "", path, why);
    }
    return image__api != NULL;
}

static void image__load(void)
{
    const char *env = getenv("BTF_IMAGE_MODULE");
    if (env && *env) {
        image__try(env);
        return;
    }
    char exe[PATH_MAX], path[PATH_MAX + 64];
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (n > 0) {
        exe[n] = 0;
        char *slash = strrchr(exe, '/');
        if (slash)
            *slash = 0;
        static const char *const up[] = {"", "/..", "/../lib/btfcodec"};
        for (size_t i = 0; i < sizeof up / sizeof *up; i++) {
            snprintf(path, sizeof path, "%s%s/%s", exe, up[i], BTF_IMAGE_MODULE_FILE);
            if (access(path, F_OK) == 0 && image__try(path))
                return;
        }
    }
    if (!image__try(BTF_IMAGE_MODULE_DIR "/" BTF_IMAGE_MODULE_FILE) && n > 0) {
        size_t used = strlen(image__why);
        snprintf(image__why + used, sizeof image__why - used, "; not beside %.300s/, nor in ../ or ../lib/btfcodec/ from it",
                 exe);
    }
}

/* The module's table, or NULL with err saying what was tried (BTF_ERR_IO). */
static const btf_image_api *image__get(const char *what, btf_error *err)
{
    pthread_once(&image__once, image__load);
    if (!image__api)
        btf_fail(err, BTF_ERR_IO, "%s: image files need the OpenImageIO module " BTF_IMAGE_MODULE_FILE
                 " (BTF_IMAGE_MODULE names it): %s", what, image__why);
    return image__api;
}

btf_result btf_image_read_u8(const char *path, int *w, int *h, int *channels, uint8_t **pixels, btf_error *err)
{
    const btf_image_api *m = image__get(path, err);
    return m ? m->read_u8(path, w, h, channels, pixels, err) : BTF_ERR_IO;
}

btf_result btf_image_info(const char *path, int *w, int *h, int *channels, btf_error *err)
{
    const btf_image_api *m = image__get(path, err);
    return m ? m->info(path, w, h, channels, err) : BTF_ERR_IO;
}

btf_result btf_image_write_flags(const char *path, int w, int h, int channels, int bits, const void *pixels, int flags,
                                 btf_error *err)
{
    const btf_image_api *m = image__get(path, err);
    return m ? m->write_flags(path, w, h, channels, bits, pixels, flags, err) : BTF_ERR_IO;
}

btf_result btf_image_encode(const char *name, int w, int h, int channels, int bits, const void *pixels, int flags,
                            uint8_t **out, size_t *n, btf_error *err)
{
    *out = NULL, *n = 0;
    const btf_image_api *m = image__get(name, err);
    return m ? m->encode(name, w, h, channels, bits, pixels, flags, out, n, err) : BTF_ERR_IO;
}

btf_result btf_image_write(const char *path, int w, int h, int channels, int bits, const void *pixels,
                           btf_error *err)
{
    return btf_image_write_flags(path, w, h, channels, bits, pixels, 0, err);
}

btf_result btf_image_write_unsynced(const char *path, int w, int h, int channels, int bits, const void *pixels,
                                    btf_error *err)
{
    return btf_image_write_flags(path, w, h, channels, bits, pixels, BTF_IMAGE_UNSYNCED, err);
}

btf_result btf_image_write_smallest(const char *stem, int w, int h, const uint8_t *grey, int flags, const char **ext,
                                    long long *bytes, btf_error *err)
{
    const btf_image_api *m = image__get(stem, err);
    return m ? m->write_smallest(stem, w, h, grey, flags, ext, bytes, err) : BTF_ERR_IO;
}

btf_result btf_image_read_grey(const char *path, int *w, int *h, uint8_t **pixels, btf_error *err)
{
    const btf_image_api *m = image__get(path, err);
    return m ? m->read_grey(path, w, h, pixels, err) : BTF_ERR_IO;
}

btf_result btf_image_info_with(const btf_files *files, const char *path, int *w, int *h, int *channels,
                               btf_error *err)
{
    const btf_image_api *m = image__get(path, err);
    return m ? m->info_with(files, path, w, h, channels, err) : BTF_ERR_IO;
}

btf_result btf_image_read_with(const btf_files *files, const char *path, int w, int h, int channels, int grey,
                               uint8_t **pixels, btf_error *err)
{
    const btf_image_api *m = image__get(path, err);
    return m ? m->read_with(files, path, w, h, channels, grey, pixels, err) : BTF_ERR_IO;
}

btf_result btf_image_read_rgb_f32(const char *path, int max_w, int max_h, int *w, int *h, float **rgb,
                                  btf_error *err)
{
    const btf_image_api *m = image__get(path, err);
    return m ? m->read_rgb_f32(path, max_w, max_h, w, h, rgb, err) : BTF_ERR_IO;
}
