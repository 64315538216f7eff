/* fuzz_dfmf.c - libFuzzer target for the DFMF08FC `.btf` reader (btf_load_dfmf,
 * codec/input/btf_dfmf.c): the input is written to a scratch file and loaded. An
 * accepted file must give a BTF within the limits with finite samples; a refused
 * one a one-line message. Memory is bounded by the reader's own limits (run
 * libFuzzer with -rss_limit_mb to catch a reader that trusts a header). */
#include "btf_io.h"
#include "fuzz_util.h"
#include "btf_input.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char path[300];
    snprintf(path, sizeof path, "%s/in.btf", fuzz_dir());
    fuzz_write(path, data, size);
    btf_load_options o = {0};
    o.storage = BTF_U8;
    btf *b = NULL;
    btf_error err = {{0}};
    if (btf_load_dfmf(path, &o, &b, &err) != BTF_OK) {
        FUZZ_CHECK(b == NULL && err.msg[0] != 0 && !strchr(err.msg, '\n'));
        return 0;
    }
    FUZZ_CHECK(b && b->width >= 1 && b->height >= 1 && b->width <= BTF_MAX_SIDE && b->height <= BTF_MAX_SIDE);
    FUZZ_CHECK((size_t)b->views.n_dirs * b->lights.n_dirs * btf_image_samples(b) <= (size_t)size * 65536);
    btf_free(b);
    return 0;
}
