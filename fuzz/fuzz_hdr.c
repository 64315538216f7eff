/* fuzz_hdr.c - libFuzzer target for environment images (btf_env_load,
 * shaders/host/btf_env.c, through btf_image_read_rgb_f32 and OpenImageIO): an
 * accepted image is at most BTF_ENV_MAX_W x BTF_ENV_MAX_H with finite, non-negative
 * radiance; a refused one says why and returns nothing. */
#include <math.h>

#include "btf_env.h"
#include "fuzz_util.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char path[300];
    snprintf(path, sizeof path, "%s/env.hdr", fuzz_dir());
    fuzz_write(path, data, size);
    btf_env *e = NULL;
    btf_error err = {{0}};
    if (btf_env_load(path, &e, &err) == BTF_OK) {
        FUZZ_CHECK(e && e->width >= 1 && e->height >= 1 && e->width <= BTF_ENV_MAX_W && e->height <= BTF_ENV_MAX_H);
        for (size_t i = 0; i < (size_t)e->width * e->height * 3; i++)
            FUZZ_CHECK(isfinite(e->rgb[i]) && e->rgb[i] >= 0.0f);
    } else {
        FUZZ_CHECK(e == NULL && err.msg[0] != 0);
    }
    btf_env_free(e);
    return 0;
}
